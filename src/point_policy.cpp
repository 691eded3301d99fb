#include "src/point_policy.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <utility>

#include "src/coupled_system.hpp"

namespace pdsim {

// The interval of R fills is t(R-1) s / sqrt(R), s the spread the fills seen so far suggest.
int more_fills(const Ensemble& e, int now, int most, double tolerance) {
  const GroupMean& m = e.mean;
  const double scale = now > 1 ? student_t975(now - 1) * std::sqrt(1 + 1.0 / now) : 0;
  const double sa = scale > 0 ? m.amplitude_spread / scale : 0;
  const double sp = scale > 0 ? m.phase_spread / scale : 0;
  int need = most;
  for (int r = now + 1; r <= most; ++r) {
    const double t = student_t975(r - 1) / std::sqrt(double(r));
    if (scale > 0 && t * sa <= tolerance * m.amplitude.mean && t * sp <= tolerance) {
      need = r;
      break;
    }
  }
  return std::min(most, std::max(now + 2, std::min(need, 2 * now)));
}

// A fill's cost at a point is the mean of the fills that ran it, or before any did, that of the
// finished points of the nearest amplitude, the point's amplitude predicted from fill 0's
// last point (the equivalent-linear model of the predicted start): near resonance, where
// the amplitude is large, fills need more periods and points more fills, on either side.
PlannedWork planned_remaining(const RunPlan& plan, const Scene& scene, const RunRecord& record,
                              const std::vector<int>& want, const std::vector<long>& target,
                              const std::vector<long>& reached) {
  struct Measured {
    double amplitude = 0, periods = 0;
    int fills = 0;
  };
  const std::size_t points = plan.points.size();
  std::vector<Measured> seen(points);
  std::vector<std::pair<double, std::size_t>> finished;  // (amplitude, point), judged points
  for (std::size_t s = 0; s < points; ++s) {
    for (std::size_t r = 0; r < record.points.size(); ++r)
      if (const auto& p = record.points[r][s]) {
        seen[s].amplitude += std::abs(p->judged.mean);
        seen[s].periods += p->judged.periods;
        ++seen[s].fills;
      }
    if (seen[s].fills > 0) {
      seen[s].amplitude /= seen[s].fills;
      seen[s].periods /= seen[s].fills;
    }
    if (record.done[s]) finished.emplace_back(seen[s].amplitude, s);
  }
  std::sort(finished.begin(), finished.end());
  // A finished point's (periods a fill, fills) interpolated at `amplitude`, in its logarithm;
  // above every finished point, nearer resonance than any yet: every fill, each with the
  // periods of the highest point. (Replayed on the Saeki example's log, growing the periods
  // with the amplitude as below it overshot the remaining time 2-3 fold, keeping the fills of
  // the highest point fell 50 % short; this was within 10 %.)
  auto learned = [&](double amplitude) -> std::pair<double, double> {
    if (finished.empty())  // not called before a point has finished (judge_ready())
      return {double(plan.settle.max_periods), double(plan.most_fills)};
    auto at = [&](std::size_t k) {
      const std::size_t s = finished[k].second;
      return std::pair<double, double>{seen[s].periods, double(want[s])};
    };
    const auto above = std::lower_bound(finished.begin(), finished.end(),
                                        std::make_pair(amplitude, std::size_t(0)));
    if (above == finished.begin()) return at(0);
    if (above == finished.end()) return {at(finished.size() - 1).first, double(plan.most_fills)};
    const auto k = static_cast<std::size_t>(above - finished.begin());
    const double a0 = std::log(finished[k - 1].first), a1 = std::log(above->first);
    const double w = a1 > a0 ? (std::log(amplitude) - a0) / (a1 - a0) : 1.0;
    const auto [p0, f0] = at(k - 1);
    const auto [p1, f1] = at(k);
    return {p0 + w * (p1 - p0), f0 + w * (f1 - f0)};
  };
  // Fill 0's last point as an effective mass and damper per damper (FrequencyRun's model).
  const FrequencyPoint* last = nullptr;
  for (std::size_t s = 0; s < points; ++s)
    if (record.points[0][s] && !record.points[0][s]->mean.container.empty())
      last = &*record.points[0][s];
  auto predicted = [&](std::size_t s) {
    if (!last || !scene.structure || last->frequency <= 0) return 0.0;
    const double w0 = 2 * kPi * last->frequency, w = 2 * kPi * plan.points[s].frequency;
    std::vector<std::complex<double>> impedance;
    for (std::size_t k = 0; k < last->mean.container.size(); ++k) {
      const std::complex<double> u = last->mean.container[k];
      const std::complex<double> z = std::abs(u) > 0 ? -last->mean.damper_force[k] / u : 0.0;
      impedance.emplace_back(z.real() / (w0 * w0) * w * w, z.imag() / w0 * w);
    }
    const DrivePhasors drive =
        drive_phasors(*scene.structure, plan.input, plan.points[s].amplitude, w);
    return std::abs((scene.structure->response.cast<std::complex<double>>() *
                     harmonic_response(*scene.structure, w, drive.load, impedance, drive.base))
                        .value());
  };
  std::vector<double> cost(points);  // simulated seconds a fill
  std::vector<int> fills(points);    // fills each point is expected to end with
  bool beyond = false;
  for (std::size_t s = 0; s < points; ++s) {
    const double amplitude = seen[s].fills > 0 ? seen[s].amplitude : predicted(s);
    const auto [periods, wanted] =
        seen[s].fills > 0 ? std::pair<double, double>{seen[s].periods, 0.0} : learned(amplitude);
    const double f = plan.points[s].frequency > 0 ? plan.points[s].frequency : 1.0;
    cost[s] = periods / f;
    beyond = beyond || (!record.done[s] && !finished.empty() && amplitude > finished.back().first);
    const double expected = seen[s].fills > 0 ? learned(seen[s].amplitude).second : wanted;
    fills[s] = record.done[s]
                   ? want[s]
                   : std::clamp(static_cast<int>(std::lround(expected)), want[s], plan.most_fills);
  }
  double remaining = 0;
  std::vector<long> reach(target);  // each fill's last point, as planned so far
  for (std::size_t r = 0; r < reach.size(); ++r)
    for (long s = reached[r] + 1; s <= reach[r]; ++s) remaining += cost[std::size_t(s)];
  for (std::size_t s = 0; s < points; ++s)
    for (auto r = std::size_t(want[s]); !record.done[s] && r < std::size_t(fills[s]); ++r)
      for (; reach[r] < static_cast<long>(s); ++reach[r])
        remaining += cost[std::size_t(reach[r] + 1)];
  return {remaining, beyond};
}

}  // namespace pdsim
