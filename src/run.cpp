#include "src/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "io/xdmf.hpp"
#include "pdsim_version.hpp"
#include "src/frequency_run.hpp"
#include "src/sweep.hpp"

namespace pdsim {

std::string number(double v, int precision) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

namespace {

volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_interrupt(int) {
  g_interrupted = 1;
  g_stop_runs = true;
}

using Clock = std::chrono::steady_clock;

// Progress on stderr: a rewritten line on a terminal, a line every few seconds otherwise. Each
// task reports how many of its frequencies it has done (with the fraction of the current one),
// or frequency 0 while its bed settles. The ETA is the remaining work at the rate of the work
// done since the beds settled (how long a bed takes to come to rest is not known in advance).
// A steady-state frequency's fraction is its periods over max_periods, an upper bound that most
// frequencies stop far below, so there only whole frequencies count towards the rate.
class Progress {
 public:
  Progress(bool quiet, std::size_t tasks, double total, bool whole)
      : quiet_(quiet),
        tty_(isatty(fileno(stderr)) != 0),
        whole_(whole),
        done_(tasks, 0.0),
        total_(total) {}
  void update(std::size_t task, double done, double frequency) {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = Clock::now();
    if (frequency > 0) {
      done_[task] = done;
      if (!working_) working_ = true, work_start_ = now;
    }
    if (now - last_ < (tty_ ? std::chrono::milliseconds(250) : std::chrono::seconds(5))) return;
    last_ = now;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const char* end = tty_ ? "   " : "\n";
    if (frequency <= 0) {
      std::fprintf(stderr, "%ssettling the bed  elapsed %.0f s%s", tty_ ? "\r" : "", elapsed, end);
    } else {
      double sum = 0, counted = 0;
      for (double d : done_) sum += d, counted += whole_ ? std::floor(d) : d;
      const double working = std::chrono::duration<double>(now - work_start_).count();
      std::fprintf(stderr, "%sf = %.3f Hz  %5.1f%%  elapsed %.0f s  ", tty_ ? "\r" : "", frequency,
                   100 * std::min(1.0, sum / total_), elapsed);
      if (counted > 0)
        std::fprintf(stderr, "ETA %.0f s%s", working * std::max(0.0, total_ - counted) / counted,
                     end);
      else
        std::fprintf(stderr, "ETA after the first %s%s", whole_ ? "frequency" : "steps", end);
    }
    std::fflush(stderr);
  }
  // A line of its own (a finished frequency), not overwritten by the progress line.
  void say(const std::string& line) {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    std::fprintf(stderr, "%s%s\n", tty_ ? "\r\033[K" : "", line.c_str());
    std::fflush(stderr);
  }
  void finish() {
    if (!quiet_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  bool quiet_, tty_, whole_, working_ = false;
  std::mutex mutex_;
  std::vector<double> done_;
  double total_;
  Clock::time_point start_ = Clock::now(), last_{}, work_start_{};
};

const char* start_name(FrequencyStart s) {
  constexpr const char* names[] = {"predicted", "carried", "independent"};
  return names[static_cast<int>(s)];
}

// A measured point as checkpoint numbers, so that a resumed run combines it as if just measured.
std::vector<double> pack(const FrequencyPoint& p) {
  const Stationary& j = p.judged;
  return {p.frequency,
          j.mean.real(),
          j.mean.imag(),
          j.amplitude_ci,
          j.phase_ci,
          double(j.discarded),
          double(j.batch_length),
          double(j.batches),
          double(j.periods),
          j.lag1,
          double(j.trend),
          double(j.converged),
          p.mean.mean_square,
          p.mean.peak,
          p.energy_in.mean,
          p.energy_in.half_width,
          p.mean.dissipated_normal,
          p.mean.dissipated_tangential,
          p.mean.dissipated_rolling,
          double(j.stationary)};
}

// The per-period harmonics of a point, five numbers a period.
std::vector<double> pack_periods(const FrequencyPoint& p) {
  std::vector<double> out;
  for (const PeriodSummary& s : p.periods)
    out.insert(out.end(), {s.displacement.real(), s.displacement.imag(), s.force.real(),
                           s.force.imag(), s.energy_in});
  return out;
}
void unpack_periods(const std::vector<double>& v, FrequencyPoint& p) {
  for (std::size_t k = 0; k + 5 <= v.size(); k += 5) {
    PeriodSummary s;
    s.displacement = {v[k], v[k + 1]};
    s.force = {v[k + 2], v[k + 3]};
    s.energy_in = v[k + 4];
    p.periods.push_back(s);
  }
}

FrequencyPoint unpack(const std::vector<double>& v) {
  // 18 numbers: written before rolling was tallied; 19 before stationary was kept.
  if (v.size() < 18 || v.size() > 20)
    throw SimulationError("checkpoint point of an unknown layout");
  FrequencyPoint p;
  Stationary& j = p.judged;
  p.frequency = v[0];
  j.mean = {v[1], v[2]};
  j.amplitude_ci = v[3];
  j.phase_ci = v[4];
  j.discarded = static_cast<int>(v[5]);
  j.batch_length = static_cast<int>(v[6]);
  j.batches = static_cast<int>(v[7]);
  j.periods = static_cast<int>(v[8]);
  j.lag1 = v[9];
  j.trend = v[10] != 0;
  j.converged = v[11] != 0;
  j.reason = j.converged ? "" : "not converged";
  p.mean.mean_square = v[12];
  p.mean.peak = v[13];
  p.energy_in = {v[14], v[15]};
  p.mean.dissipated_normal = v[16];
  p.mean.dissipated_tangential = v[17];
  p.mean.dissipated_rolling = v.size() > 18 ? v[18] : std::nan("");  // not measured
  j.stationary = v.size() > 19 ? v[19] != 0 : j.converged;
  return p;
}

// A fill settled on its own: its mean known to the tolerance, or held still when max_periods
// ended it (a run stops before max_periods only when converged).
bool settled(const Stationary& j) {
  return j.converged || j.stationary;
}

// The ensemble of a point's fills (judge_ensemble(); with settle.max_realisations fills no
// more will come). A fixed run asked for no tolerance: it is a result when every fill's
// periods are stationary, and adds no fills.
Ensemble judge_fills(const std::vector<FrequencyPoint>& runs, const ExcitationSpec& x) {
  std::vector<FillValue> fills;
  for (const FrequencyPoint& p : runs)
    fills.push_back({p.judged.mean, p.judged.amplitude_ci, p.judged.phase_ci, p.judged.batches - 1,
                     settled(p.judged)});
  const bool last = static_cast<int>(runs.size()) >= x.settle.max_realisations;
  Ensemble e = judge_ensemble(fills, x.settle.tolerance, last);
  if (fixed_duration(x)) {
    const bool all = std::all_of(runs.begin(), runs.end(),
                                 [](const FrequencyPoint& p) { return p.judged.converged; });
    e.result = !all                  ? PointResult::none
               : e.branch.size() > 1 ? PointResult::branches
                                     : PointResult::one_state;
    e.wants_fills = false;
    e.reason = all ? "" : "drifting or too short for an interval";
  }
  return e;
}

// "0.4605 mm +- 0.25 %" (prescribed motion: "force 1.2 N +- 3 %").
std::string amplitude_text(double size, double half_width, bool prescribed) {
  std::ostringstream s;
  s.precision(4);
  s << (prescribed ? "force " : "") << size * (prescribed ? 1.0 : 1e3)
    << (prescribed ? " N" : " mm") << " +- " << 100 * half_width / std::max(size, 1e-300) << " %";
  return s.str();
}

// One line for the log: a point's ensemble, its branches, and what it is.
std::string ensemble_text(const Ensemble& e, bool prescribed) {
  std::ostringstream s;
  s.precision(4);
  const GroupMean& m = e.mean;
  s << m.fills << (m.fills == 1 ? " fill: " : " fills: ")
    << amplitude_text(m.amplitude.mean, m.amplitude.half_width, prescribed);
  if (m.fills > 1)
    s << " (one fill within +- " << 100 * m.amplitude_spread / std::max(m.amplitude.mean, 1e-300)
      << " %)";
  s << ", phase " << m.phase.mean << " +- " << m.phase.half_width << " rad";
  if (e.branch.size() > 1) {
    s << "; " << e.branch.size() << " branches:";
    for (const GroupMean& b : e.branch)
      s << " " << amplitude_text(b.amplitude.mean, b.amplitude.half_width, prescribed) << " at "
        << b.phase.mean << " rad (" << b.fills << " of " << m.fills << ")";
  }
  s << (e.result == PointResult::one_state  ? "; a result"
        : e.result == PointResult::branches ? "; a result of several branches"
                                            : "; NOT a result: " + e.reason);
  return s.str();
}

// One row of /frf or /prescribed (with its /periods, /frf/fills and /frf/branch_means) from
// the fills of one point: (fill index, what it measured).
void add_row(Results& out, const std::vector<std::pair<int, FrequencyPoint>>& fills, int sweep,
             const ExcitationSpec& x) {
  const bool prescribed = x.kind == ExcitationKind::prescribed;
  std::vector<FrequencyPoint> runs;
  for (const auto& [r, p] : fills) runs.push_back(p);
  const Ensemble e = judge_fills(runs, x);
  const GroupMean& m = e.mean;
  std::vector<RunMean> energy;
  std::vector<double> rms, dn, dt, dr;
  double peak = 0;
  int periods = 0, discarded = 0;
  for (const FrequencyPoint& p : runs) {
    energy.push_back({p.energy_in.mean, p.energy_in.half_width, p.judged.batches - 1});
    rms.push_back(std::sqrt(p.mean.mean_square));
    peak = std::max(peak, p.mean.peak);
    dn.push_back(p.mean.dissipated_normal);
    dt.push_back(p.mean.dissipated_tangential);
    dr.push_back(p.mean.dissipated_rolling);
    periods = std::max(periods, p.judged.periods);
    discarded = std::max(discarded, p.judged.discarded);
  }
  const MeanInterval energy_in = combine_runs(energy, 0).interval;
  auto average = [](const std::vector<double>& values) {
    double s = 0;
    for (double v : values) s += v;
    return s / double(values.size());
  };
  const double frequency = runs[0].frequency;
  const int count = static_cast<int>(runs.size());
  const int interval = count == 1 ? 0 : m.consistent ? 1 : 2;
  const int converged = e.result != PointResult::none ? 1 : 0;
  for (const auto& [r, point] : fills)
    for (std::size_t k = 0; k < point.periods.size(); ++k) {
      const PeriodSummary& p = point.periods[k];
      PeriodTable& t = out.periods;
      t.frequency.push_back(frequency);
      t.realisation.push_back(r);
      t.period.push_back(static_cast<int>(k));
      t.stationary.push_back(static_cast<int>(k) >= point.judged.discarded ? 1 : 0);
      t.amplitude.push_back(std::abs(p.displacement));
      t.phase.push_back(std::arg(p.displacement));
      t.force_amplitude.push_back(std::abs(p.force));
      t.force_phase.push_back(std::arg(p.force));
      t.energy_in.push_back(p.energy_in);
    }
  if (prescribed) {
    PrescribedTable& p = out.prescribed;
    p.frequency.push_back(frequency);
    p.dissipated_power.push_back(energy_in.mean * frequency);
    p.dissipated_power_ci.push_back(energy_in.half_width * frequency);
    p.force_amplitude.push_back(m.amplitude.mean);
    p.force_amplitude_ci.push_back(m.amplitude.half_width);
    p.force_phase.push_back(m.phase.mean);
    p.force_phase_ci.push_back(m.phase.half_width);
    p.periods.push_back(periods);
    p.periods_discarded.push_back(discarded);
    p.converged.push_back(converged);
    p.realisations.push_back(count);
    p.interval.push_back(interval);
    return;
  }
  FrfTable& f = out.frf;
  f.frequency.push_back(frequency);
  f.sweep.push_back(sweep);
  f.amplitude.push_back(m.amplitude.mean);
  f.amplitude_ci.push_back(m.amplitude.half_width);
  f.amplitude_spread.push_back(m.amplitude_spread);
  f.phase.push_back(m.phase.mean);
  f.phase_ci.push_back(m.phase.half_width);
  f.phase_spread.push_back(m.phase_spread);
  f.result.push_back(static_cast<int>(e.result));
  f.branches.push_back(static_cast<int>(e.branch.size()));
  f.rms.push_back(average(rms));
  f.peak.push_back(peak);
  f.periods.push_back(periods);
  f.periods_discarded.push_back(discarded);
  f.converged.push_back(converged);
  f.realisations.push_back(count);
  f.interval.push_back(interval);
  f.dissipated_energy.push_back(energy_in.mean);
  f.dissipated_energy_ci.push_back(energy_in.half_width);
  f.dissipated_normal.push_back(average(dn));
  f.dissipated_tangential.push_back(average(dt));
  f.dissipated_rolling.push_back(average(dr));
  for (std::size_t k = 0; k < fills.size(); ++k) {
    const auto& [r, p] = fills[k];
    FillTable& t = out.fills;
    t.frequency.push_back(frequency);
    t.sweep.push_back(sweep);
    t.realisation.push_back(r);
    t.branch.push_back(e.branch_of[k]);
    t.amplitude.push_back(std::abs(p.judged.mean));
    t.amplitude_ci.push_back(p.judged.amplitude_ci);
    t.phase.push_back(std::arg(p.judged.mean));
    t.phase_ci.push_back(p.judged.phase_ci);
    t.periods.push_back(p.judged.periods);
    t.converged.push_back(p.judged.converged ? 1 : 0);
    t.settled.push_back(settled(p.judged) ? 1 : 0);
  }
  for (std::size_t b = 0; b < e.branch.size(); ++b) {
    const GroupMean& g = e.branch[b];
    BranchTable& t = out.branch_means;
    t.frequency.push_back(frequency);
    t.sweep.push_back(sweep);
    t.branch.push_back(static_cast<int>(b));
    t.fills.push_back(g.fills);
    t.share.push_back(g.share);
    t.share_low.push_back(g.share_low);
    t.share_high.push_back(g.share_high);
    t.amplitude.push_back(g.amplitude.mean);
    t.amplitude_ci.push_back(g.amplitude.half_width);
    t.phase.push_back(g.phase.mean);
    t.phase_ci.push_back(g.phase.half_width);
    t.within_tolerance.push_back(g.within(x.settle.tolerance) ? 1 : 0);
  }
}
// Everything that decides a settled bed: a bed file made for other particles is refused.
std::string bed_fingerprint(const Deck& deck, const Scene& scene) {
  std::ostringstream s;
  s.precision(17);
  s << "dt " << scene.dt << " speed " << deck.bed.speed << " max_time " << deck.bed.max_time;
  if (deck.gravity)
    s << " g " << deck.gravity->x << " " << deck.gravity->y << " " << deck.gravity->z;
  const ContactSpec& c = deck.contact;
  s << " contact " << int(c.model) << " " << int(c.tangential) << " " << c.young << " " << c.poisson
    << " " << c.restitution << " " << c.friction << " " << c.stiffness << " " << c.rolling_friction;
  for (const DamperScene& d : scene.dampers) {
    const EngineConfig& e = d.engine;
    s << " | " << int(e.shape) << " " << e.geometry.half_size.x << " " << e.geometry.half_size.y
      << " " << e.geometry.half_size.z << " " << e.density << " " << e.radius.size();
    // The fill itself, as an FNV-1a hash of its radii and positions.
    std::uint64_t hash = 1469598103934665603ull;
    auto mix = [&](double v) {
      unsigned char bytes[sizeof v];
      std::memcpy(bytes, &v, sizeof v);
      for (unsigned char b : bytes) hash = (hash ^ b) * 1099511628211ull;
    };
    for (double r : e.radius) mix(r);
    for (const ParticleState& p : e.particles)
      mix(p.position.x), mix(p.position.y), mix(p.position.z);
    s << " " << hash;
  }
  return s.str();
}

// Runs a deck's excitation on its fills (realisations: fill seeds seed + r). A point (one
// frequency of one sweep) starts with settle.realisations fills; while the ensemble mean is
// not known to the tolerance, fills are added up to settle.max_realisations. In a carried
// sweep every fill carries its state from one point to the next, so that a fill added at a
// point first catches up: it runs every earlier point from its own settled bed, to its own
// criterion, exactly as a fill carried all the way (its values there join those points). With
// start = "independent" a task is one point, its fills from their own beds, the tasks side by
// side. Fills run `jobs` at a time; what a fill computes never depends on that schedule.
class Driver {
 public:
  using SceneMaker = std::function<Scene(int fill)>;
  Driver(const Deck& deck, Scene first, SceneMaker make_scene, int jobs, bool quiet,
         std::string dump_path)
      : deck_(deck),
        make_scene_(std::move(make_scene)),
        jobs_(jobs),
        quiet_(quiet),
        dump_path_(std::move(dump_path)) {
    const ExcitationSpec& x = first.excitation;
    const bool swept =
        x.kind == ExcitationKind::stepped_sine || x.kind == ExcitationKind::prescribed;
    fills_min_ = swept ? x.settle.realisations : 1;
    fills_max_ = swept && !fixed_duration(x) ? x.settle.max_realisations : fills_min_;
    frequencies_ = first.frequencies;
    sweeps_ = x.sweeps;
    sweeps_.resize(frequencies_.size(), 1);
    const auto fills = static_cast<std::size_t>(fills_max_), steps = frequencies_.size();
    scenes_.resize(fills);
    scenes_[0] = std::make_unique<Scene>(std::move(first));
    points_.assign(fills, std::vector<std::optional<FrequencyPoint>>(steps));
    done_.assign(steps, 0);
    beds_.resize(fills);
    reports_.resize(fills);
    runs_.resize(fills);
    reached_.assign(fills, -1);
    seen_.resize(fills);
    bed_once_ = std::make_unique<std::once_flag[]>(fills);
  }

  void resume_from(const Results& partial) {
    const StateArrays& c = partial.checkpoint;
    results_.timeseries = partial.timeseries;
    results_.energy = partial.energy;
    results_.particles = partial.particles;
    bed_from_file_ = c.count("bed.from_file") > 0;
    const auto& done = state_values<std::int32_t>(c, "run.done");
    if (done.size() != done_.size())
      throw SimulationError("the checkpoint's run.done should hold one flag a frequency");
    for (std::size_t s = 0; s < done.size(); ++s) done_[s] = done[s] != 0;
    const auto filled = static_cast<std::size_t>(state_value<std::int32_t>(c, "run.fills"));
    for (std::size_t r = 0; r < filled && r < beds_.size(); ++r) {
      beds_[r] = get_state(c, "bed.r" + std::to_string(r) + ".");
      if (!beds_[r].empty()) reports_[r] = unpack_report(c, r);
      for (std::size_t i = 0; i < frequencies_.size(); ++i)
        if (const auto it = c.find(point_key(r, i)); it != c.end()) {
          points_[r][i] = unpack(state_values<double>(c, point_key(r, i)));
          unpack_periods(state_values<double>(c, point_key(r, i) + ".periods"), *points_[r][i]);
          reached_[r] = static_cast<long>(i);
        }
      if (StateArrays state = get_state(c, "task.r" + std::to_string(r) + "."); !state.empty())
        task_states_[r] = std::move(state);
    }
    if (independent()) {  // fill 0's segments, by the frequency each sample was taken at
      const TimeSeries& ts = partial.timeseries;
      for (std::size_t j = 0; j < ts.frequency.size(); ++j) {
        const auto at = std::find(frequencies_.begin(), frequencies_.end(), ts.frequency[j]);
        if (at == frequencies_.end()) continue;
        TimeSeries& segment = segments_[static_cast<std::size_t>(at - frequencies_.begin())];
        std::vector<const std::vector<double>*> from;
        timeseries_columns(ts, [&](const char*, const auto& column, const char*, const char*) {
          from.push_back(&column);
        });
        std::size_t next = 0;
        timeseries_columns(segment, [&](const char*, auto& column, const char*, const char*) {
          column.push_back((*from[next++])[j]);
        });
      }
    }
    const auto& totals = state_values<double>(c, "run.totals");
    particle_steps_ = static_cast<long long>(totals.at(0));
    simulated_ = totals.at(1);
    wall_before_ = totals.at(2);
  }

  Results run(const std::function<void(const Results&)>& checkpoint, int stop_after) {
    started_ = Clock::now();
    g_stop_runs = g_interrupted != 0;  // an interrupt before the start stops it at once
    checkpoint_ = checkpoint;
    stop_after_ = stop_after;
    const ExcitationSpec& x = excitation();
    if (x.kind == ExcitationKind::free_decay || x.kind == ExcitationKind::sine) {
      Progress progress(quiet_, 1, 1.0, false);
      FrequencyRun run(scene(0), [&](double f, double done) { progress.update(0, done, f); });
      try {
        reports_[0] = run.settle_bed();
        if (x.kind == ExcitationKind::free_decay) {
          run.run_free_decay();
        } else {
          points_[0][0] = run.run_frequency(x.frequency, FrequencyStart::carried);
          done_[0] = 1;
        }
      } catch (const SimulationError& e) {
        fail(run, 0, e);
      }
      results_.timeseries = run.timeseries();
      results_.energy = run.energy();
      results_.particles = run.particles();
      Seen from_start;
      account(run, from_start);
      progress.finish();
    } else {
      run_tasks();
    }
    if (!stopped_) add_rows(results_);
    wall_ = wall_before_ + std::chrono::duration<double>(Clock::now() - started_).count();
    provenance(results_);
    return results_;
  }

  bool stopped() const { return stopped_; }
  // What a failed run had computed, or nullptr (see fail()).
  const Results* failed() const { return failed_ ? &*failed_ : nullptr; }
  std::size_t finished() const { return finished_; }

 private:
  static std::string point_key(std::size_t r, std::size_t i) {
    return "point.r" + std::to_string(r) + ".f" + std::to_string(i);
  }
  const ExcitationSpec& excitation() const { return scenes_[0]->excitation; }
  bool independent() const { return excitation().start == FrequencyStart::independent; }
  bool prescribed() const { return excitation().kind == ExcitationKind::prescribed; }

  // Fill r's scene, built when it is first needed.
  const Scene& scene(std::size_t r) {
    std::lock_guard<std::mutex> lock(scene_mutex_);
    if (!scenes_[r]) scenes_[r] = std::make_unique<Scene>(make_scene_(static_cast<int>(r)));
    return *scenes_[r];
  }

  // The fills that have run point s, with what they measured.
  std::vector<std::pair<int, FrequencyPoint>> fills_at(std::size_t s) const {
    std::vector<std::pair<int, FrequencyPoint>> fills;
    for (std::size_t r = 0; r < points_.size(); ++r)
      if (points_[r][s]) fills.emplace_back(static_cast<int>(r), *points_[r][s]);
    return fills;
  }
  // Point s judged on its fills 0..count-1 (the ones it asked for: fills that ran it on their
  // way to a later point join it only in the rows, so that no decision depends on the order
  // fills run in), or on all that ran it.
  Ensemble judge_step(std::size_t s, std::size_t count = SIZE_MAX) const {
    std::vector<FrequencyPoint> runs;
    for (const auto& [r, p] : fills_at(s))
      if (static_cast<std::size_t>(r) < count) runs.push_back(p);
    return judge_fills(runs, excitation());
  }

  // The /frf (or /prescribed) rows of every finished point, in the order they are run.
  void add_rows(Results& out) const {
    for (std::size_t s = 0; s < frequencies_.size(); ++s)
      if (done_[s]) add_row(out, fills_at(s), sweeps_[s], excitation());
  }

  // Adds what `run` did since `seen` (its particle steps and simulated time) to the totals.
  struct Seen {
    long long steps = 0;
    double time = 0;
  };
  void account(const FrequencyRun& run, Seen& seen) {
    particle_steps_ += run.system().particle_steps() - seen.steps;
    simulated_ += run.system().time() - seen.time;
    seen = {run.system().particle_steps(), run.system().time()};
    if (!backend_.empty()) return;
    const auto& engines = run.system().engines();
    backend_ = engines.empty() ? std::string("none (no particles)") : engines[0]->backend();
    variant_ = engines.empty() ? std::string("none") : engines[0]->variant();
    threads_ = engines.empty() ? 1 : engines[0]->threads();
  }

  // Runs `work(k)` for k = 0..count-1, `jobs_` at a time; the first failure stops the others
  // and is rethrown (a stop asked for by stop_after is not a failure).
  void in_parallel(std::size_t count, const std::function<void(std::size_t)>& work) {
    std::atomic<std::size_t> next{0};
    std::exception_ptr failure;
    std::mutex failure_mutex;
    auto worker = [&] {
      for (std::size_t k; (k = next++) < count && !g_stop_runs;) {
        try {
          work(k);
        } catch (...) {
          std::lock_guard<std::mutex> lock(failure_mutex);
          if (!failure && !stopped_) failure = std::current_exception();
          g_stop_runs = true;
        }
      }
    };
    const std::size_t workers = std::min<std::size_t>(count, static_cast<std::size_t>(jobs_));
    std::vector<std::thread> threads;
    for (std::size_t w = 1; w < workers; ++w) threads.emplace_back(worker);
    worker();
    for (auto& t : threads) t.join();
    if (failure) std::rethrow_exception(failure);
    // A stop that came between tasks (SIGINT) leaves work undone without any task failing.
    if (g_stop_runs && !stopped_) throw Interrupted();
  }

  // Dumps the particles of a failed run beside the output and says where.
  // Also keeps what the failed run computed (its time series up to the failure, the finished
  // frequencies) for failed(): a run that blows up in its only segment would otherwise leave
  // nothing but the particle dump.
  [[noreturn]] void fail(const FrequencyRun& run, std::size_t r, const SimulationError& e) {
    if (g_interrupted || dump_path_.empty() || dynamic_cast<const Interrupted*>(&e)) throw;
    run.system().dump(dump_path_);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!failed_) {
        Results& f = failed_.emplace(results_);
        if (!independent() && r == 0)
          f.timeseries = run.timeseries(), f.energy = run.energy(), f.particles = run.particles();
        add_rows(f);
        provenance(f);
        f.meta_text["failure"] = e.what();
      }
    }
    throw SimulationError(std::string(e.what()) + "\nparticle states written to " + dump_path_);
  }

  // The settled beds and their reports ("bed.reports": four numbers a fill) of the fills
  // 0..count-1, into a checkpoint or a bed file.
  void put_beds(StateArrays& c, std::size_t count) const {
    std::vector<double> reports;
    for (std::size_t r = 0; r < count; ++r) {
      put_state(c, "bed.r" + std::to_string(r) + ".", beds_[r]);
      reports.insert(reports.end(), {double(reports_[r].ran), double(reports_[r].settled),
                                     reports_[r].time_s, reports_[r].speed});
    }
    c["bed.reports"] = reports;
  }
  static BedReport unpack_report(const StateArrays& c, std::size_t r) {
    const std::vector<double>& v = state_values<double>(c, "bed.reports");
    if (v.size() < 4 * (r + 1))
      throw SimulationError("the checkpoint's bed.reports should hold 4 values a realisation");
    return {v[4 * r] != 0, v[4 * r + 1] != 0, v[4 * r + 2], v[4 * r + 3]};
  }

  // The beds of the first fills (settle.realisations): from bed.file when it holds them (with
  // any further fills it holds), else settled side by side (and written there).
  void settle_beds(Progress& progress) {
    const auto first = static_cast<std::size_t>(fills_min_);
    std::vector<std::size_t> missing;
    for (std::size_t r = 0; r < first; ++r)
      if (beds_[r].empty()) missing.push_back(r);
    if (missing.empty()) return;
    const std::string& file = scenes_[0]->bed.file;
    const std::string fingerprint = bed_fingerprint(deck_, *scenes_[0]);
    if (!file.empty() && std::filesystem::exists(file)) {
      Results saved = read_results(file);
      const auto held = static_cast<std::size_t>(saved.meta_numbers["realisations"]);
      if (saved.meta_text["bed_fingerprint"] != fingerprint || held < first)
        throw InputError(
            deck_.where("bed.file"), "bed.file",
            "'" + file +
                "' holds a bed settled for other particles, container, "
                "contact, gravity, dt or realisations; delete it or name another file");
      for (std::size_t r = 0; r < std::min(held, beds_.size()); ++r)
        if (beds_[r].empty()) {
          beds_[r] = get_state(saved.checkpoint, "bed.r" + std::to_string(r) + ".");
          reports_[r] = unpack_report(saved.checkpoint, r);
        }
      bed_from_file_ = true;
      return;
    }
    in_parallel(missing.size(), [&](std::size_t k) { settle_bed(missing[k], progress); });
    if (!file.empty()) {
      Results saved;
      saved.meta_text["bed_fingerprint"] = fingerprint;
      saved.meta_text["deck"] = deck_.text;
      saved.meta_numbers["realisations"] = double(first);
      put_beds(saved.checkpoint, first);
      write_results(file, saved, true);
    }
  }
  void settle_bed(std::size_t r, Progress& progress) {
    FrequencyRun run(scene(r), [&](double f, double done) { progress.update(r, done, f); });
    BedReport report;
    try {
      report = run.settle_bed();
    } catch (const SimulationError& e) {
      fail(run, r, e);
    }
    std::lock_guard<std::mutex> lock(mutex_);
    reports_[r] = report;
    beds_[r] = run.save();
    Seen from_start;
    account(run, from_start);
  }
  // Fill r's bed, settled the first time a fill beyond the first ones needs it.
  void ensure_bed(std::size_t r, Progress& progress) {
    std::call_once(bed_once_[r], [&] {
      if (beds_[r].empty()) settle_bed(r, progress);
    });
  }

  void run_tasks() {
    std::size_t todo = 0;
    for (char d : done_) todo += d ? 0 : 1;
    // Progress: a slot per fill (carried) or per point (independent); the first fills' work.
    const std::size_t slots = independent() ? frequencies_.size() : beds_.size();
    const double total = double(todo) * (independent() ? fills_min_ : 1);
    Progress progress(quiet_, std::max(slots, beds_.size()), std::max(total, 1.0),
                      !fixed_duration(excitation()));
    progress_ = &progress;
    settle_beds(progress);
    if (independent())
      run_independent(progress);
    else
      run_carried(progress);
    progress.finish();
  }

  // How many fills the point should have next: enough for a Student-t interval of the spread
  // seen (t(R-1) s / sqrt(R)) to meet the tolerance, at least two more, at most twice as many.
  int more_fills(const Ensemble& e, int now) const {
    const double tolerance = excitation().settle.tolerance;
    const GroupMean& m = e.mean;
    const double scale = now > 1 ? student_t975(now - 1) * std::sqrt(1 + 1.0 / now) : 0;
    const double sa = scale > 0 ? m.amplitude_spread / scale : 0;
    const double sp = scale > 0 ? m.phase_spread / scale : 0;
    int need = fills_max_;
    for (int r = now + 1; r <= fills_max_; ++r) {
      const double t = student_t975(r - 1) / std::sqrt(double(r));
      if (scale > 0 && t * sa <= tolerance * m.amplitude.mean && t * sp <= tolerance) {
        need = r;
        break;
      }
    }
    return std::min(fills_max_, std::max(now + 2, std::min(need, 2 * now)));
  }
  std::string point_name(std::size_t s) const {
    bool both = false;
    for (int sweep : sweeps_) both = both || sweep != sweeps_[0];
    return "f = " + number(frequencies_[s]) + " Hz" +
           (both ? (sweeps_[s] > 0 ? " (up)" : " (down)") : "");
  }
  void say_adding(std::size_t s, const Ensemble& e, int now, int next) {
    progress_->say(point_name(s) + ": " + ensemble_text(e, prescribed()) + "; " +
                   std::to_string(next - now) + " more fills (" + std::to_string(next) + " of " +
                   std::to_string(fills_max_) + ")");
  }

  // A carried sweep. Every fill is a sweep of its own, so fills run independently, `jobs_` at
  // a time: the first fills (settle.realisations) through every point; a point is judged once
  // each fill it wants has run it, and when it wants more, fills beyond the first are sent to
  // it (catching up from their beds through the points before). Which fill a worker takes
  // changes only the order of the work, never what a fill computes.
  void run_carried(Progress& progress) {
    const auto last = static_cast<long>(frequencies_.size()) - 1;
    want_.assign(frequencies_.size(), fills_min_);
    target_.assign(beds_.size(), -1);
    busy_.assign(beds_.size(), 0);
    for (std::size_t r = 0; r < static_cast<std::size_t>(fills_min_); ++r) target_[r] = last;
    std::unique_lock<std::mutex> lock(mutex_);
    judge_ready();
    std::exception_ptr failure;
    std::condition_variable changed;
    auto worker = [&] {
      std::unique_lock<std::mutex> held(mutex_);
      for (;;) {
        if (g_stop_runs) return;
        // The fill furthest behind first: points then finish about in order.
        std::size_t pick = beds_.size();
        bool running = false;
        for (std::size_t r = 0; r < beds_.size(); ++r) {
          running = running || busy_[r];
          if (!busy_[r] && reached_[r] < target_[r] &&
              (pick == beds_.size() || reached_[r] < reached_[pick]))
            pick = r;
        }
        if (pick == beds_.size()) {
          if (!running) return;  // nothing left to run, and nothing running could add any
          changed.wait(held);
          continue;
        }
        busy_[pick] = 1;
        held.unlock();
        try {
          run_next_point(pick, progress);
        } catch (...) {
          held.lock();
          if (!failure && !stopped_) failure = std::current_exception();
          g_stop_runs = true;
          busy_[pick] = 0;
          changed.notify_all();
          return;
        }
        held.lock();
        busy_[pick] = 0;
        judge_ready();
        changed.notify_all();
      }
    };
    lock.unlock();
    std::vector<std::thread> threads;
    for (int w = 1; w < jobs_; ++w) threads.emplace_back(worker);
    worker();
    for (auto& t : threads) t.join();
    if (failure) std::rethrow_exception(failure);
    if (g_stop_runs && !stopped_) throw Interrupted();
  }

  // Judges every point whose wanted fills have all run it (mutex_ held): finished, or more
  // fills sent to it.
  void judge_ready() {
    for (std::size_t s = 0; s < frequencies_.size(); ++s) {
      if (done_[s]) continue;
      bool ready = true;
      for (std::size_t r = 0; r < static_cast<std::size_t>(want_[s]); ++r)
        ready = ready && points_[r][s].has_value();
      if (!ready) continue;
      const Ensemble e = judge_step(s, static_cast<std::size_t>(want_[s]));
      if (e.wants_fills && want_[s] < fills_max_) {
        const int next = more_fills(e, want_[s]);
        say_adding(s, e, want_[s], next);
        for (auto r = static_cast<std::size_t>(want_[s]); r < static_cast<std::size_t>(next); ++r)
          target_[r] = std::max(target_[r], static_cast<long>(s));
        want_[s] = next;
        continue;
      }
      finished_step(s);
      if (stopped_) return;
    }
  }

  // Runs fill r's next point (a fill's first from its settled bed) and records it.
  void run_next_point(std::size_t r, Progress& progress) {
    if (!runs_[r]) {
      ensure_bed(r, progress);
      std::lock_guard<std::mutex> lock(mutex_);  // task_states_ and results_ are shared
      runs_[r] = std::make_unique<FrequencyRun>(scene(r), [this, r, &progress](double f, double d) {
        progress.update(r, double(reached_[r] + 1) + d, f);
      });
      FrequencyRun& run = *runs_[r];
      if (const auto it = task_states_.find(r); it != task_states_.end()) {
        run.restore(it->second);
        if (r == 0) run.set_records(results_.timeseries, results_.energy, results_.particles);
      } else {
        run.restore(beds_[r]);
      }
      seen_[r] = {run.system().particle_steps(), run.system().time()};
    }
    FrequencyRun& run = *runs_[r];
    const auto k = static_cast<std::size_t>(reached_[r] + 1);
    FrequencyPoint point;
    try {
      point = run.run_frequency(frequencies_[k], excitation().start);
    } catch (const SimulationError& e) {
      fail(run, r, e);
    }
    StateArrays state = checkpoint_ ? run.save() : StateArrays{};
    std::lock_guard<std::mutex> lock(mutex_);
    points_[r][k] = std::move(point);
    reached_[r] = static_cast<long>(k);
    if (checkpoint_) task_states_[r] = std::move(state);
    account(run, seen_[r]);
    if (r == 0) {
      results_.timeseries = run.timeseries();
      results_.energy = run.energy();
      results_.particles = run.particles();
    }
    const bool catching_up = r >= static_cast<std::size_t>(want_[k]);
    progress_->say(describe(*points_[r][k], r) + (catching_up ? " (catching up)" : ""));
  }

  // Independent points side by side, each point's fills in turn from their settled beds.
  void run_independent(Progress& progress) {
    std::vector<std::size_t> todo;
    for (std::size_t s = 0; s < frequencies_.size(); ++s)
      if (!done_[s]) todo.push_back(s);
    in_parallel(todo.size(), [&](std::size_t k) {
      const std::size_t s = todo[k];
      double done = 0;
      for (int want = fills_min_;;) {
        for (std::size_t r = 0; r < static_cast<std::size_t>(want); ++r, done += 1) {
          if (points_[r][s]) continue;
          ensure_bed(r, progress);
          FrequencyRun run(scene(r),
                           [&, k](double f, double d) { progress.update(k, done + d, f); });
          run.restore(beds_[r]);
          Seen seen{run.system().particle_steps(), run.system().time()};
          FrequencyPoint point;
          try {
            point = run.run_frequency(frequencies_[s], excitation().start);
          } catch (const SimulationError& e) {
            fail(run, r, e);
          }
          std::lock_guard<std::mutex> lock(mutex_);
          points_[r][s] = std::move(point);
          account(run, seen);
          if (r == 0) append_segment(run.timeseries(), s);
          progress_->say(describe(*points_[r][s], r));
        }
        const Ensemble e = judge_step(s);
        if (!e.wants_fills || want >= fills_max_) break;
        const int next = more_fills(e, want);
        say_adding(s, e, want, next);
        want = next;
      }
      std::lock_guard<std::mutex> lock(mutex_);
      finished_step(s);
    });
  }

  // Marks point s finished, tells the log, and writes a checkpoint while points remain
  // (mutex_ held).
  void finished_step(std::size_t s) {
    ++finished_;
    done_[s] = 1;
    const Ensemble e = judge_step(s);
    progress_->say(point_name(s) + ": " + ensemble_text(e, prescribed()));
    if (std::all_of(done_.begin(), done_.end(), [](char d) { return d != 0; }) || !checkpoint_)
      return;
    std::size_t fills = 0;  // fills 0..fills-1 have begun
    for (std::size_t r = 0; r < beds_.size(); ++r)
      if (!beds_[r].empty()) fills = r + 1;
    Results snapshot = results_;
    add_rows(snapshot);  // the finished points are readable (and plottable) in the .partial
    StateArrays& c = snapshot.checkpoint;
    put_beds(c, fills);
    c["run.fills"] = std::vector<std::int32_t>{static_cast<std::int32_t>(fills)};
    c["run.done"] = std::vector<std::int32_t>(done_.begin(), done_.end());
    if (bed_from_file_) c["bed.from_file"] = std::vector<std::int32_t>{1};
    for (std::size_t k = 0; k < fills; ++k)
      for (std::size_t f = 0; f < frequencies_.size(); ++f)
        if (points_[k][f]) {
          c[point_key(k, f)] = pack(*points_[k][f]);
          c[point_key(k, f) + ".periods"] = pack_periods(*points_[k][f]);
        }
    for (const auto& [k, state] : task_states_)
      put_state(c, "task.r" + std::to_string(k) + ".", state);
    c["run.totals"] = std::vector<double>{
        double(particle_steps_), simulated_,
        wall_before_ + std::chrono::duration<double>(Clock::now() - started_).count()};
    provenance(snapshot);
    checkpoint_(snapshot);
    if (stop_after_ > 0 && --stop_after_ == 0) {
      stopped_ = true;
      g_stop_runs = true;
    }
  }

  // Independent frequencies: fill 0's time series, one segment per frequency (each from the
  // settled bed's time), kept in the order of the frequency list.
  void append_segment(const TimeSeries& segment, std::size_t index) {
    segments_[index] = segment;
    TimeSeries all;
    std::vector<std::vector<double>*> to;
    timeseries_columns(
        all, [&](const char*, auto& column, const char*, const char*) { to.push_back(&column); });
    for (const auto& [k, part] : segments_) {
      std::size_t c = 0;
      timeseries_columns(part, [&](const char*, const auto& column, const char*, const char*) {
        to[c]->insert(to[c]->end(), column.begin(), column.end());
        ++c;
      });
    }
    results_.timeseries = all;
  }

  std::string describe(const FrequencyPoint& p, std::size_t r) const {
    std::ostringstream s;
    s.precision(4);
    s << "f = " << p.frequency << " Hz";
    if (fills_max_ > 1) s << " (fill " << r + 1 << ")";
    s << ": " << amplitude_text(std::abs(p.judged.mean), p.judged.amplitude_ci, prescribed())
      << ", " << p.judged.periods << " periods (" << p.judged.discarded << " warm-up)";
    if (fixed_duration(excitation()))
      s << ", fixed duration" << (p.judged.converged ? "" : ", " + p.judged.reason);
    else
      s << (p.judged.converged  ? ", settled"
            : settled(p.judged) ? ", held still (" + p.judged.reason + ")"
                                : ", NOT settled: " + p.judged.reason);
    return s.str();
  }

  void provenance(Results& r) const {
    auto& t = r.meta_text;
    auto& n = r.meta_numbers;
    t["deck"] = deck_.text;
    t["deck_path"] = deck_.path;
    if (deck_.point > 0)
      t["sweep_point"] = std::to_string(deck_.point) + ": " + deck_.sweep.describe(deck_.point);
    t["title"] = deck_.title;
    t["version"] = std::string(PDSIM_VERSION) + " (" + PDSIM_GIT + ")";
    t["backend"] = backend_.empty() ? "none (no particles)" : backend_;
    t["kernel_variant"] = variant_.empty() ? "none" : variant_;
    const char* schemes[] = {"loose", "interleaved", "tight"};
    const Scene& scene = *scenes_[0];
    t["coupling"] = schemes[static_cast<int>(scene.coupling.scheme)];
    t["dt_basis"] = scene.dt_basis;
    if (!scene.warning.empty()) t["warning"] = scene.warning;
    const ExcitationKind kind = excitation().kind;
    if (kind == ExcitationKind::stepped_sine || kind == ExcitationKind::prescribed)
      t["start"] = start_name(excitation().start);
    const BedReport& bed = reports_[0];
    t["bed"] = !bed.ran         ? "not settled (bed.settle = false, or no gravity or particles)"
               : bed_from_file_ ? "read from " + scene.bed.file
               : bed.settled
                   ? "settled in " + number(bed.time_s) + " s"
                   : "NOT settled within bed.max_time = " + number(scene.bed.max_time) + " s";
    n["bed_settled"] = bed.settled ? 1 : 0;
    n["bed_settle_time_s"] = bed.time_s;
    n["bed_speed"] = bed.speed;
    n["realisations"] = double(fills_min_);
    n["max_realisations"] = double(fills_max_);
    std::size_t used = 0;
    for (std::size_t k = 0; k < points_.size(); ++k)
      for (const auto& p : points_[k]) used = p ? std::max(used, k + 1) : used;
    n["fills_used"] = double(used);
    n["jobs"] = jobs_;
    n["threads"] = threads_;
    n["dt"] = scene.dt;
    n["dt_limit"] = scene.dt_limit;
    n["wall_time_s"] = wall_;
    n["particle_steps"] = double(particle_steps_);
    int particles = 0;
    for (const DamperScene& d : scene.dampers)
      particles += static_cast<int>(d.engine.particles.size());
    n["particles"] = particles;
    n["simulated_time_s"] = simulated_;
  }

  const Deck& deck_;
  SceneMaker make_scene_;
  std::vector<std::unique_ptr<Scene>> scenes_;  // one per fill, built when first needed
  std::mutex scene_mutex_;
  int jobs_;
  bool quiet_;
  std::string dump_path_;
  int fills_min_ = 1, fills_max_ = 1;
  std::vector<double> frequencies_;  // of the points, in the order they are run
  std::vector<int> sweeps_;          // +1 up, -1 down, per point
  std::vector<std::vector<std::optional<FrequencyPoint>>> points_;  // [fill][point]
  std::vector<char> done_;                                          // per point
  std::vector<StateArrays> beds_;
  std::vector<BedReport> reports_;
  std::unique_ptr<std::once_flag[]> bed_once_;
  std::vector<std::unique_ptr<FrequencyRun>> runs_;  // carried: each fill's run
  std::vector<long> reached_;  // carried: the last point each fill ran (-1: none)
  std::vector<long> target_;   // carried: the last point each fill is to run
  std::vector<int> want_;      // carried: the fills each point wants
  std::vector<char> busy_;     // carried: a worker is running the fill
  std::vector<Seen> seen_;
  std::map<std::size_t, StateArrays> task_states_;
  std::map<std::size_t, TimeSeries> segments_;
  Results results_;
  std::function<void(const Results&)> checkpoint_;
  Progress* progress_ = nullptr;
  std::mutex mutex_;
  int stop_after_ = 0;
  std::atomic<bool> stopped_{false};
  bool bed_from_file_ = false;
  std::optional<Results> failed_;
  std::size_t finished_ = 0;  // points finished in this process
  long long particle_steps_ = 0;
  double simulated_ = 0, wall_ = 0, wall_before_ = 0;
  Clock::time_point started_ = Clock::now();
  std::string backend_, variant_;
  int threads_ = 1;
};

// The frequencies whose flag is `value`, comma-separated (with the sweep when both ran).
std::string listed(const std::vector<double>& frequency, const std::vector<int>& sweep,
                   const std::vector<int>& flag, int value) {
  const bool both = std::find(sweep.begin(), sweep.end(), -sweep.front()) != sweep.end();
  std::string list;
  for (std::size_t i = 0; i < frequency.size(); ++i)
    if (flag[i] == value)
      list += (list.empty() ? "" : ", ") + number(frequency[i]) +
              (both ? (sweep[i] > 0 ? " (up)" : " (down)") : "");
  return list;
}

std::string summary_line(const Results& r, const std::string& path, const Deck& deck) {
  std::ostringstream s;
  s.precision(4);
  const bool fixed = fixed_duration(deck.excitation);
  if (!r.frf.frequency.empty() && deck.excitation.kind == ExcitationKind::stepped_sine) {
    const FrfTable& f = r.frf;
    int results = 0, branched = 0;
    for (int k : f.result) results += k > 0, branched += k == 2;
    s << "FRF: " << f.frequency.size() << " points, " << results << " results";
    if (branched > 0) s << " (" << branched << " of several branches)";
    const FrfPeak peak = frf_peak(f, r.fills);
    if (peak.found)
      s << "; peak amplitude " << 1e3 * peak.amplitude << " +- " << 1e3 * peak.amplitude_ci
        << " mm at " << peak.frequency << " Hz (the mean over its fills; highest single fill "
        << 1e3 * peak.upper << " mm)";
    // The hard part stays in the headline: the largest mean where the point is not a result.
    if (peak.higher)
      s << "; HIGHER where not a result: " << 1e3 * peak.higher_amplitude << " +- "
        << 1e3 * peak.higher_amplitude_ci << " mm at " << peak.higher_frequency << " Hz";
    if (results < static_cast<int>(f.frequency.size()))
      s << "; NOT results at " << listed(f.frequency, f.sweep, f.result, 0)
        << " Hz (a fill still drifting at settle.max_periods, or settle.max_realisations "
           "fills agreeing on one state whose mean is not known to settle.tolerance)";
    if (branched > 0)
      s << "; several branches at " << listed(f.frequency, f.sweep, f.result, 2)
        << " Hz (fills of the same damper in distinct states, the mean's interval their "
           "spread: /frf/fills, /frf/branch_means)";
  } else if (!r.frf.frequency.empty()) {
    s << "sine at " << r.frf.frequency[0] << " Hz: first harmonic " << 1e3 * r.frf.amplitude[0]
      << " +- " << 1e3 * r.frf.amplitude_ci[0] << " mm"
      << (r.frf.converged[0] ? "" : " (not stationary over the duration)");
  } else if (!r.prescribed.frequency.empty()) {
    const PrescribedTable& p = r.prescribed;
    int count = 0;
    for (int c : p.converged) count += c;
    std::size_t k = 0;  // the peak over the result points (fixed runs: over all)
    bool found = false;
    for (std::size_t i = 0; i < p.frequency.size(); ++i)
      if ((fixed || p.converged[i]) && (!found || p.dissipated_power[i] > p.dissipated_power[k]))
        k = i, found = true;
    const std::vector<int> sweep(p.frequency.size(), 1);
    s << "prescribed motion: " << p.frequency.size()
      << (p.frequency.size() == 1 ? " frequency" : " frequencies");
    if (fixed)
      s << ", " << deck.excitation.duration << " s each";
    else
      s << ", " << count << " results";
    if (found)
      s << "; " << (p.frequency.size() == 1 ? "" : "peak ") << "power " << p.dissipated_power[k]
        << " +- " << p.dissipated_power_ci[k] << " W at " << p.frequency[k] << " Hz";
    if (count < static_cast<int>(p.frequency.size()))
      s << (fixed ? "; drifting or too short for an interval at " : "; NOT results at ")
        << listed(p.frequency, sweep, p.converged, 0) << " Hz" << (fixed ? " (run longer)" : "");
  } else {
    s << "time history: " << r.timeseries.time.size() << " samples";
  }
  s << "; wall time " << r.meta_numbers.at("wall_time_s") << " s, "
    << r.meta_numbers.at("particle_steps") / std::max(1e-9, r.meta_numbers.at("wall_time_s"))
    << " particle-steps/s -> " << path;
  return s.str();
}

}  // namespace

std::string output_path(const Deck& deck, const RunOptions& options) {
  if (!options.output.empty()) return options.output;
  if (deck.point > 0)
    return (std::filesystem::path(sweep_folder(deck)) / point_file(deck, deck.point)).string();
  if (!deck.output.file.empty()) return deck.output.file;
  return std::filesystem::path(deck.path).stem().string() + ".h5";
}

namespace {

// The first fill's scene, how to build any other fill's (fill seeds seed + r of every damper),
// and how many runs go side by side: one per core unless told, the cores shared out.
struct Plan {
  Scene first;
  std::function<Scene(int)> make_scene;
  int jobs = 1;
};

Plan plan_run(const Deck& deck, const Scene& scene, int threads, int jobs,
              std::optional<Backend> backend) {
  const ExcitationSpec& x = deck.excitation;
  const bool swept = x.kind == ExcitationKind::stepped_sine || x.kind == ExcitationKind::prescribed;
  const int realisations = swept ? x.settle.realisations : 1;
  // Side by side: the first fills, or with independent frequencies the frequencies (each task
  // runs its fills in turn, Driver::run_independent()).
  const int tasks = swept && x.start == FrequencyStart::independent
                        ? static_cast<int>(x.frequencies.size())
                        : realisations;
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int total = threads > 0 ? threads : deck.solver.threads > 0 ? deck.solver.threads : cores;
  const int side_by_side = std::max(1, std::min(tasks, jobs > 0 ? jobs : total));
  const int each = tasks > 1 ? std::max(1, total / side_by_side) : threads;
  auto make = [deck, each, backend](int r) {
    Deck seeded = deck;
    for (DamperSpec& d : seeded.dampers) d.particles.seed += static_cast<std::uint64_t>(r);
    return build_scene(seeded, each, backend);
  };
  return {each == threads ? scene : make(0), make, side_by_side};
}

}  // namespace

Results simulate(const Deck& deck, const Scene& scene, bool quiet, int jobs) {
  Plan plan = plan_run(deck, scene, scene.threads, jobs, std::nullopt);
  Driver driver(deck, std::move(plan.first), plan.make_scene, plan.jobs, quiet, "");
  return driver.run({}, 0);
}

// Free space below which a run warns before it starts, bytes.
constexpr std::uintmax_t kLowSpace = 64u << 20;

// SIGINT handled from the start of a run (a sweep's point may get it while it sets up) until
// its end.
struct InterruptScope {
  void (*previous)(int);
  InterruptScope() : previous(std::signal(SIGINT, on_interrupt)) {}
  ~InterruptScope() { std::signal(SIGINT, previous); }
};

RunReport run_deck(const Deck& deck, const RunOptions& options) {
  const InterruptScope interrupts;
  const std::string path = output_path(deck, options);
  const std::string partial = path + ".partial";
  namespace fs = std::filesystem;
  if (deck.sweep.points() > 0 && deck.point == 0)
    throw InputError(deck.path + ": the deck has a [sweep] table of " +
                     std::to_string(deck.sweep.points()) +
                     " points; run them all with `pdsim sweep`, or one with `pdsim run --point K`");
  // Everything about the output that can be known before computing is checked first.
  if (path.empty() || path.find('\0') != std::string::npos)
    throw InputError("output file: expected a path without NUL characters, got '" + path + "'");
  std::error_code ignored;  // a path that cannot be examined is treated as absent
  if (fs::is_directory(path, ignored))
    throw InputError(path + ": is a folder; expected the path of an output file");
  if (fs::exists(path, ignored) && !options.force)
    throw InputError(path + ": output file exists; use --force to overwrite it");
  const fs::path folder = fs::path(path).parent_path();
  if (deck.point > 0 && !folder.empty()) fs::create_directories(folder, ignored);
  if (!folder.empty() && !fs::is_directory(folder, ignored))
    throw InputError(path + ": the folder " + folder.string() + " does not exist");
  const fs::path place = folder.empty() ? fs::path(".") : folder;
  if (access(place.c_str(), W_OK | X_OK) != 0)
    throw InputError(path + ": the folder " + place.string() + " is not writable");
  // A full disk costs no finished work (the last checkpoint survives), but say it early.
  if (const auto space = fs::space(place, ignored); space.available < kLowSpace)
    std::cerr << "warning: only " << space.available / (1 << 20) << " MiB free for " << path
              << "; a full disk stops the run (exit 2, the last checkpoint kept)\n";
  std::optional<OutputLock> lock;
  try {
    lock.emplace(path);
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
  // Temporary files a killed run left behind (OUT.tmp-PID, OUT.partial.tmp-PID): with the lock
  // held, no other pdsim is writing them.
  const std::string stem = fs::path(path).filename().string();
  for (const auto& entry : fs::directory_iterator(place, ignored)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(stem + ".tmp-", 0) == 0 || name.rfind(stem + ".partial.tmp-", 0) == 0)
      fs::remove(entry.path(), ignored);
  }
  const Scene scene = build_scene(deck, options.threads, options.backend);
  if (!scene.warning.empty()) std::cerr << "warning: " << scene.warning << "\n";
  Plan plan = plan_run(deck, scene, options.threads, options.jobs, options.backend);
  Driver driver(deck, std::move(plan.first), plan.make_scene, plan.jobs, options.quiet,
                path + ".blowup.csv");
  if (options.resume) {
    if (!fs::exists(partial))
      throw InputError(partial + ": nothing to resume (no checkpoint of an interrupted run)");
    Results saved = read_results(partial);
    if (saved.meta_text["deck"] != deck.text)
      throw InputError(partial +
                       ": the deck changed since the interrupted run; run it anew "
                       "without --resume");
    if (saved.checkpoint.empty())
      throw InputError(partial + ": holds no checkpoint; run it anew without --resume");
    driver.resume_from(saved);
  }
  Results results;
  try {
    results = driver.run([&](const Results& snapshot) { write_results(path, snapshot, false); },
                         options.stop_after);
  } catch (const SimulationError& e) {
    if (const Results* failed = driver.failed()) {
      const std::string kept = path + ".failed.h5";
      try {
        write_unfinished(kept, *failed);
      } catch (const std::exception& unwritten) {
        throw SimulationError(std::string(e.what()) + "\n(not kept: " + unwritten.what() + ")");
      }
      throw SimulationError(std::string(e.what()) +
                            "\nwhat was computed up to the failure: " + kept);
    }
    if (g_interrupted && !fs::exists(partial))
      throw Interrupted("interrupted before the first frequency finished; nothing kept");
    if (g_interrupted)
      throw Interrupted(std::string("interrupted; finished frequencies are in ") + partial +
                        ", continue with --resume");
    throw;
  }
  if (driver.stopped())
    return {partial, "stopped after " + std::to_string(driver.finished()) +
                         " frequencies as asked; continue with --resume"};
  write_results(path, results, true, options.force);
  std::string summary = summary_line(results, path, deck);
  if (results.particles) {
    write_xdmf(path, *results.particles);
    summary += "; particles: " + xdmf_path(path) + " (ParaView)";
  }
  return {path, summary};
}

std::string check_report(const Deck& deck, const Scene& scene) {
  std::ostringstream s;
  s.precision(5);
  s << "deck: " << deck.path << (deck.title.empty() ? "" : " (" + deck.title + ")") << "\n";
  double structure_mass = 0;
  if (deck.structure.kind != StructureKind::none) {
    const std::vector<double>& f = scene.natural_hz;
    structure_mass =
        deck.structure.kind == StructureKind::sdof
            ? deck.structure.mass
            : deck.structure.beam.density * deck.structure.beam.area * deck.structure.beam.length;
    s << "structure: " << (deck.structure.kind == StructureKind::sdof ? "sdof" : "beam")
      << ", mass " << structure_mass << " kg, first natural frequency " << f.front() << " Hz\n";
  } else {
    s << "structure: none (prescribed container motion)\n";
  }
  double steps_per_second = 0;
  long total_particles = 0;
  for (std::size_t k = 0; k < scene.dampers.size(); ++k) {
    const DamperScene& d = scene.dampers[k];
    const auto n = d.engine.particles.size();
    total_particles += static_cast<long>(n);
    s << "damper " << k << ": " << n << " particles, mass " << d.particle_mass << " kg ("
      << d.particle_mass / static_cast<double>(n) << " kg each), fill fraction " << d.fill_fraction;
    if (structure_mass > 0) s << ", mass ratio " << d.particle_mass / structure_mass;
    s << "\n  kernel variant: " << variant_name(d.engine) << "\n";
  }
  if (!scene.dampers.empty()) {
    s << "contact time: " << scene.contact_time << " s"
      << (deck.contact.model == NormalModel::hertz ? " (Hertz, binary impact at 1 m/s)" : "")
      << "\n";
    if (scene.rayleigh_time > 0) s << "Rayleigh time: " << scene.rayleigh_time << " s\n";
    s << "dt: " << scene.dt << " s (" << scene.dt_basis << "; limit " << scene.dt_limit << " s)\n";
    if (!scene.warning.empty()) s << "WARNING: " << scene.warning << "\n";
    steps_per_second = 1.0 / scene.dt;
  }
  s << "backend: " << backend_name(scene.backend) << " (" << scene.backend_reason << ")\n";
  if (scene.highest_frequency() > 0) {
    s << "steps per period: "
      << static_cast<long>(std::ceil(1.0 / (scene.highest_frequency() * scene.dt))) << " at "
      << scene.highest_frequency() << " Hz\n";
  }
  const ExcitationSpec& x = deck.excitation;
  const SettleSpec& settle = x.settle;
  const bool judged = x.kind != ExcitationKind::free_decay && !fixed_duration(x);
  if (judged)
    s << "frequencies: " << x.frequencies.size() << ", start = " << start_name(x.start)
      << "; steady when the 95 % interval is within " << 100 * settle.tolerance << " % ("
      << settle.min_periods << " to " << settle.max_periods << " periods, " << settle.batches
      << " batches; " << settle.realisations
      << (settle.max_realisations > settle.realisations
              ? " to " + std::to_string(settle.max_realisations) +
                    " fills, added where they disagree"
          : settle.realisations > 1 ? " fills"
                                    : " fill")
      << ")\n";
  if (deck.bed.settle)
    s << "bed: settled under gravity first, until no particle moves faster than " << deck.bed.speed
      << " m/s for " << kBedHold_s << " s (at most " << deck.bed.max_time << " s)"
      << (deck.bed.file.empty() ? "" : "; kept in " + deck.bed.file) << "\n";
  // Estimated cost: simulated time x steps/s x particles, at an assumed 1e7 particle-steps/s.
  double simulated = 0;
  if (judged)
    for (double f :
         (x.frequencies.empty() ? std::vector<double>{x.motion.frequency} : x.frequencies))
      simulated += settle.max_realisations * settle.max_periods / f;
  else
    simulated = x.duration * static_cast<double>(std::max<std::size_t>(1, x.frequencies.size()));
  s << "simulated time: at most " << simulated << " s";
  if (total_particles > 0) {
    const double particle_steps =
        simulated * steps_per_second * static_cast<double>(total_particles);
    s << ", at most " << number(particle_steps, 3) << " particle-steps (about "
      << number(particle_steps / 1e7, 2) << " s at 1e7 particle-steps/s)";
  }
  s << "\n";
  return s.str();
}

}  // namespace pdsim
