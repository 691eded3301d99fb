#include "src/predict.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include "io/excitation.hpp"
#include "pdsim_version.hpp"
#include "src/identity.hpp"
#include "src/coupled_system.hpp"
#include "src/format.hpp"
#include "src/run_plan.hpp"

namespace pdsim {

namespace {

// Frequencies of a deck and of a map are the same doubles when they are the same list entries;
// a rounding's worth of difference still names the same one.
bool same_frequency(double a, double b) {
  return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b));
}

constexpr int kScanPoints = 2000;  // log-spaced amplitudes searched for sign changes
constexpr int kBisections = 80;
// A root whose map_change exceeds this is named: on the beam damper a cell of 4-7 mm through the
// onset of impacts (map_change 1.0-1.4) put the peak 8-17 % low; with points every 0.5 mm there
// (at most 0.34) it was within 3 %.
constexpr double kCoarse = 0.5;

// "" for points run from the settled bed, else the way the amplitudes were stepped.
std::string way(int sweep) {
  return sweep > 0 ? " (stepped up)" : sweep < 0 ? " (stepped down)" : "";
}

}  // namespace

MapInterpolant::MapInterpolant(const MapTable& map, int sweep) {
  std::map<double, Row> by_frequency;
  for (std::size_t i = 0; i < map.frequency.size(); ++i) {
    if (map.sweep.at(i) != sweep) continue;
    double f = map.frequency[i];
    // Maps merged from a {start, stop, step} table and a list hold 13.3 as two doubles.
    for (const auto& [g, row] : by_frequency)
      if (same_frequency(f, g)) f = g;
    const double x = map.amplitude[i], w = 2 * kPi * f;
    if (!(f > 0) || !(x > 0) || !std::isfinite(map.effective_mass[i]) ||
        !std::isfinite(map.effective_damping[i]))
      throw InputError("the map's row " + std::to_string(i) +
                       " holds no finite effective mass and damping at a positive frequency and "
                       "amplitude");
    Row& r = by_frequency[f];
    r.frequency = f;
    r.amplitude.push_back(x);
    r.real.push_back(w * w * map.effective_mass[i] * x);
    r.imag.push_back(w * map.effective_damping[i] * x);
    r.real_ci.push_back(w * w * map.effective_mass_ci[i] * x);
    r.imag_ci.push_back(w * map.effective_damping_ci[i] * x);
    r.converged.push_back(map.converged.at(i));
  }
  for (auto& [f, r] : by_frequency) {
    std::vector<std::size_t> order(r.amplitude.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return r.amplitude[a] < r.amplitude[b]; });
    Row sorted{f, {}, {}, {}, {}, {}, {}};
    for (std::size_t k : order) {
      if (!sorted.amplitude.empty() && sorted.amplitude.back() == r.amplitude[k])
        throw InputError("the map holds amplitude " + number(r.amplitude[k]) + " m twice at " +
                         number(f) + " Hz" + way(sweep));
      sorted.amplitude.push_back(r.amplitude[k]);
      sorted.real.push_back(r.real[k]);
      sorted.imag.push_back(r.imag[k]);
      sorted.real_ci.push_back(r.real_ci[k]);
      sorted.imag_ci.push_back(r.imag_ci[k]);
      sorted.converged.push_back(r.converged[k]);
    }
    if (sorted.amplitude.size() < 2)
      throw InputError("the map holds one amplitude at " + number(f) +
                       " Hz; harmonic balance interpolates between two or more");
    rows_.push_back(std::move(sorted));
  }
  if (rows_.empty()) throw InputError("the map holds no points");
}

std::pair<std::size_t, double> MapInterpolant::bracket(double frequency) const {
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    if (same_frequency(frequency, rows_[j].frequency)) return {j, 0.0};
    if (j + 1 < rows_.size() && same_frequency(frequency, rows_[j + 1].frequency))
      return {j + 1, 0.0};
    if (j + 1 < rows_.size() && frequency > rows_[j].frequency &&
        frequency < rows_[j + 1].frequency)
      return {j, (frequency - rows_[j].frequency) / (rows_[j + 1].frequency - rows_[j].frequency)};
  }
  return {rows_.size(), 0.0};  // outside
}

std::pair<double, double> MapInterpolant::amplitudes(double frequency) const {
  const auto [j, t] = bracket(frequency);
  if (j == rows_.size()) return {0.0, 0.0};
  const Row& a = rows_[j];
  if (t == 0) return {a.amplitude.front(), a.amplitude.back()};
  const Row& b = rows_[j + 1];
  return {std::max(a.amplitude.front(), b.amplitude.front()),
          std::min(a.amplitude.back(), b.amplitude.back())};
}

MapInterpolant::Value MapInterpolant::at_row(const Row& r, double x) const {
  const auto upper = std::upper_bound(r.amplitude.begin(), r.amplitude.end(), x);
  std::size_t k = static_cast<std::size_t>(upper - r.amplitude.begin());
  k = std::clamp<std::size_t>(k, 1, r.amplitude.size() - 1) - 1;
  const double t = (x - r.amplitude[k]) / (r.amplitude[k + 1] - r.amplitude[k]);
  auto lerp = [&](const std::vector<double>& v) { return v[k] + t * (v[k + 1] - v[k]); };
  const double w = 2 * kPi * r.frequency;
  auto z = [&](std::size_t i) {
    return std::complex<double>(r.real[i], r.imag[i]) / r.amplitude[i];
  };
  return {lerp(r.real) / (w * w * x),    lerp(r.imag) / (w * x),
          lerp(r.real_ci) / (w * w * x), lerp(r.imag_ci) / (w * x),
          std::abs(z(k + 1) - z(k)),     r.converged[k] != 0 && r.converged[k + 1] != 0};
}

MapInterpolant::Value MapInterpolant::at(double frequency, double amplitude) const {
  const auto [j, t] = bracket(frequency);
  const Value a = at_row(rows_.at(j), amplitude);
  if (t == 0) return a;
  const Value b = at_row(rows_.at(j + 1), amplitude);
  auto lerp = [t = t](double u, double v) { return u + t * (v - u); };
  return {lerp(a.mass, b.mass),       lerp(a.damping, b.damping),
          lerp(a.mass_ci, b.mass_ci), lerp(a.damping_ci, b.damping_ci),
          std::max(a.step, b.step),   a.converged && b.converged};
}

HostAt host_at(const LinearStructure& s, ExcitationInput input, double amplitude,
               double frequency) {
  HostAt h;
  h.omega = 2 * kPi * frequency;
  const DrivePhasors drive = drive_phasors(s, input, amplitude, h.omega);
  h.load = drive.load;
  h.base = drive.base;
  const Eigen::RowVectorXd row = s.attachment_translation.row(0);
  const Eigen::RowVectorXcd t = row.cast<std::complex<double>>();
  h.shift = {0.0, h.omega * h.omega * (row * s.mass * row.transpose()).value()};
  const std::vector<std::complex<double>> held(s.attachment_translation.rows(), h.shift);
  h.bare = h.base + (t * harmonic_response(s, h.omega, h.load, held, h.base)).value();
  h.receptance = (t * harmonic_response(s, h.omega, t.transpose(), held, 0.0)).value();
  return h;
}

std::vector<HbRoot> harmonic_balance(const MapInterpolant& map, const LinearStructure& s,
                                     const HostAt& host, double frequency) {
  const auto [lo, hi] = map.amplitudes(frequency);
  if (hi <= 0)
    throw InputError("frequency " + number(frequency) + " Hz is outside the map's frequencies (" +
                     number(map.lowest_frequency()) + " to " + number(map.highest_frequency()) +
                     " Hz); extend the map's [map] frequencies");
  if (lo >= hi)
    throw InputError("at " + number(frequency) +
                     " Hz the map's amplitudes at the frequencies either side do not overlap; "
                     "map more frequencies or a wider range of accelerations");
  const double w = host.omega;
  auto impedance = [&](double x) {
    const MapInterpolant::Value v = map.at(frequency, x);
    return std::complex<double>(-v.mass * w * w, w * v.damping);
  };
  // X |1 + (Z(X) - Z0) H| - |G|: negative where the drive outweighs the damper's motion.
  auto h = [&](double x) {
    return x * std::abs(1.0 + (impedance(x) - host.shift) * host.receptance) - std::abs(host.bare);
  };
  // The structure's reported displacement with the damper acting as the impedance z.
  auto response = [&](std::complex<double> z) {
    const std::vector<std::complex<double>> damper(s.attachment_translation.rows(), z);
    return (s.response.cast<std::complex<double>>() *
            harmonic_response(s, w, host.load, damper, host.base))
        .value();
  };
  if (h(lo) > 0)
    throw InputError("at " + number(frequency) +
                     " Hz the damper's amplitude is below the map's smallest there (" + number(lo) +
                     " m); extend the map to smaller amplitudes");
  if (h(hi) < 0)
    throw InputError("at " + number(frequency) +
                     " Hz the damper's amplitude is above the map's largest there (" + number(hi) +
                     " m); extend the map to larger amplitudes");
  std::vector<HbRoot> roots;
  const double ratio = std::pow(hi / lo, 1.0 / (kScanPoints - 1));
  double a = lo, ha = h(lo);
  for (int k = 1; k < kScanPoints; ++k) {
    const double b = k == kScanPoints - 1 ? hi : a * ratio, hb = h(b);
    if ((ha < 0) != (hb < 0)) {
      double left = a, right = b, hl = ha;
      for (int n = 0; n < kBisections && right - left > 1e-14 * right; ++n) {
        const double mid = 0.5 * (left + right), hm = h(mid);
        if ((hm < 0) == (hl < 0))
          left = mid, hl = hm;
        else
          right = mid;
      }
      HbRoot r;
      const double x = 0.5 * (left + right);
      r.damper_amplitude = x;
      r.damper = map.at(frequency, x);
      const std::complex<double> z = impedance(x), u = response(z);
      r.amplitude = std::abs(u);
      r.phase = std::arg(u);
      // Slow amplitude changes grow X where the drive outweighs the damper's motion (h < 0): a
      // root where h rises is stable, one where it falls (the middle of a jump) is not.
      const double step = 1e-6 * x;
      const double up = std::min(hi, x + step), down = std::max(lo, x - step);
      const double slope = (h(up) - h(down)) / (up - down);
      r.stable = slope > 0;
      // The map's intervals to first order: moving its impedance by dz at X moves h by
      // X Re(conj(q) H dz) / |q| (q = 1 + (Z - Z0) H), the root by dX = -dh / slope, and Z along
      // the map by Z'(X) dX; the response follows Z.
      const std::complex<double> q = 1.0 + (z - host.shift) * host.receptance;
      r.map_change = r.damper.step * std::abs(host.receptance) / std::abs(q);
      const std::complex<double> dz_dx = (impedance(up) - impedance(down)) / (up - down);
      auto moved = [&](std::complex<double> dz) {
        const double dx = -x * std::real(std::conj(q) * host.receptance * dz) / std::abs(q) / slope;
        return std::abs(std::abs(response(z + dz + dz_dx * dx)) - r.amplitude);
      };
      r.amplitude_ci = std::hypot(moved({-w * w * r.damper.mass_ci, 0.0}),
                                  moved({0.0, w * r.damper.damping_ci}));
      // A turning point (slope 0) or a map point without an interval: no bound.
      if (!std::isfinite(r.amplitude_ci)) r.amplitude_ci = std::numeric_limits<double>::infinity();
      roots.push_back(r);
    }
    a = b, ha = hb;
  }
  return roots;
}

RunReport run_predict(const Deck& deck, const PredictOptions& options) {
  namespace fs = std::filesystem;
  const auto started = std::chrono::steady_clock::now();
  if (deck.structure.kind == StructureKind::none)
    throw InputError(deck.path + ": pdsim predict needs a [structure] to put the damper on");
  if (deck.dampers.size() != 1)
    throw InputError(deck.where("damper"), "damper",
                     "expected one [[damper]] for pdsim predict (a map is one damper's), got " +
                         std::to_string(deck.dampers.size()));
  const ExcitationSpec& x = deck.excitation;
  if (traits(x.kind).moves_containers || !measures_harmonics(x))
    throw InputError(deck.where("excitation.kind"), "excitation.kind",
                     "expected \"stepped_sine\" or \"sine\" for pdsim predict");
  // The maps as one: their rows together, of one damper (the deck's).
  Results source;
  // Built on the CPU: a prediction needs no device, whatever the deck's backend.
  const Scene scene = build_scene(deck, 1, Backend::cpu);
  const Identity damper = deck_identity(deck, scene);
  for (const std::string& file : options.maps) {
    if (!fs::exists(file)) throw InputError(file + ": no such map file");
    Results one = read_results(file);
    if (one.map.frequency.empty())
      throw InputError(file + ": holds no /map (a file that pdsim map writes)");
    if (!one.meta_text.count("identity") || one.map.sweep.size() != one.map.frequency.size())
      throw InputError(file +
                       ": a map from a pdsim before maps recorded their damper field by field; "
                       "make it again from its finished runs with pdsim map DECK --resume (its "
                       "runs are kept)");
    if (const std::string differ =
            identity_difference(parse_identity(one.meta_text["identity"]), damper,
                                IdentityScope::design, "in the map", "in the deck");
        !differ.empty())
      throw InputError(file + ": a map of another damper than the deck's (" + differ + ")");
    append_rows(source.map, one.map);
  }
  std::vector<std::pair<int, MapInterpolant>> maps;
  for (int sweep : {0, 1, -1})
    if (std::count(source.map.sweep.begin(), source.map.sweep.end(), sweep))
      maps.emplace_back(sweep, MapInterpolant(source.map, sweep));
  std::string names;
  for (const std::string& file : options.maps) names += (names.empty() ? "" : ", ") + file;

  const std::string path = options.output.empty() ? output_beside(deck, "_hb.h5") : options.output;
  if (fs::exists(path) && !options.force)
    throw InputError(path + ": output file exists; use --force to overwrite it");

  std::vector<double> frequencies = x.frequencies;
  std::sort(frequencies.begin(), frequencies.end());
  frequencies.erase(std::unique(frequencies.begin(), frequencies.end()), frequencies.end());
  const LinearStructure& structure = *scene.structure;
  Results r;
  HbTable& t = r.frf_hb;
  std::vector<std::string> refused;
  std::size_t several = 0, apart = 0;  // frequencies with several roots; up and down apart
  std::vector<double> coarse;          // frequencies with a root where the map is coarse
  std::vector<double> unsettled;       // frequencies with a root read from unconverged points
  for (double f : frequencies) {
    bool many = false, coarse_here = false, unsettled_here = false;
    std::vector<std::pair<int, const HbRoot*>> stable;  // (sweep, root)
    const HostAt host = host_at(structure, x.input, x.amplitude, f);
    if (!std::isfinite(std::abs(host.receptance)) || !std::isfinite(std::abs(host.bare))) {
      refused.push_back("at " + number(f) +
                        " Hz the structure's response at the damper is not finite (an undamped "
                        "mode there)");
      continue;
    }
    // Each way of the map gives the roots it can (a stepped map may cover only the resonance,
    // or only some amplitudes); a frequency that no way can solve is refused with their reasons.
    std::vector<std::vector<HbRoot>> found(maps.size());
    std::vector<std::string> reasons;
    for (std::size_t m = 0; m < maps.size(); ++m) try {
        found[m] = harmonic_balance(maps[m].second, structure, host, f);
      } catch (const InputError& e) {
        reasons.push_back(e.what() + way(maps[m].first));
      }
    if (reasons.size() == maps.size()) {
      refused.insert(refused.end(), reasons.begin(), reasons.end());
      continue;
    }
    for (std::size_t m = 0; m < maps.size(); ++m) {
      const std::vector<HbRoot>& roots = found[m];
      many = many || roots.size() > 1;
      for (std::size_t b = 0; b < roots.size(); ++b) {
        t.frequency.push_back(f);
        t.sweep.push_back(maps[m].first);
        t.branch.push_back(static_cast<int>(b));
        t.amplitude.push_back(roots[b].amplitude);
        t.amplitude_ci.push_back(roots[b].amplitude_ci);
        t.damper_amplitude.push_back(roots[b].damper_amplitude);
        t.phase.push_back(roots[b].phase);
        t.stable.push_back(roots[b].stable ? 1 : 0);
        t.effective_mass.push_back(roots[b].damper.mass);
        t.effective_damping.push_back(roots[b].damper.damping);
        t.map_change.push_back(roots[b].map_change);
        t.map_converged.push_back(roots[b].damper.converged ? 1 : 0);
        unsettled_here = unsettled_here || !roots[b].damper.converged;
        coarse_here = coarse_here || roots[b].map_change > kCoarse;
        if (roots[b].stable) stable.emplace_back(maps[m].first, &roots[b]);
      }
    }
    several += many ? 1 : 0;
    if (coarse_here) coarse.push_back(f);
    if (unsettled_here) unsettled.push_back(f);
    // Stable roots of the ways up and down further apart than their intervals: the bed's
    // hysteresis (several roots of one way are branches, counted above).
    bool differ = false;
    for (const auto& [way_a, a] : stable)
      for (const auto& [way_b, b] : stable)
        differ =
            differ || (way_a > 0 && way_b < 0 &&
                       std::abs(a->amplitude - b->amplitude) > a->amplitude_ci + b->amplitude_ci);
    apart += differ ? 1 : 0;
  }
  if (!refused.empty()) {
    std::string what = names + " does not cover the deck's response (nothing written):";
    for (const std::string& e : refused) what += "\n  " + e;
    throw InputError(what);
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  r.meta_text["deck"] = deck.text;
  r.meta_text["deck_path"] = deck.path;
  r.meta_text["title"] = deck.title;
  r.meta_text["maps"] = names;
  r.meta_text["version"] = std::string(PDSIM_VERSION) + " (" + PDSIM_GIT + ")";
  r.meta_numbers["wall_time_s"] = wall;
  write_results(path, r, true, true);

  std::optional<std::size_t> peak;  // the highest stable root
  for (std::size_t i = 0; i < t.frequency.size(); ++i)
    if (t.stable[i] && (!peak || t.amplitude[i] > t.amplitude[*peak])) peak = i;
  std::ostringstream s;
  s << "harmonic balance from " << names << ": " << frequencies.size() << " frequencies, "
    << several << " with several branches";
  if (maps.size() > 1) s << ", " << apart << " where the map's ways up and down give other states";
  s << "; ";
  if (!coarse.empty()) {
    s << "the map is coarse (between the amplitudes a root lies between its impedance moves by "
         "more than "
      << kCoarse * 100 << " % of the balance, /frf_hb/map_change; map more amplitudes there) at";
    for (double f : coarse) s << " " << number(f);
    s << " Hz; ";
  }
  if (!unsettled.empty())
    s << "at " << unsettled.size() << " of " << frequencies.size()
      << " frequencies a root is read from map points that did not converge (wide intervals: "
         "/frf_hb/map_converged); ";
  if (peak)
    s << "peak of the stable branches " << number(1e3 * t.amplitude[*peak]) << " mm at "
      << number(t.frequency[*peak]) << " Hz";
  else
    s << "no stable root";
  s << "; " << number(1e3 * wall) << " ms";
  return {path, s.str()};
}

}  // namespace pdsim
