#include "src/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
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
          p.mean.dissipated_rolling};
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
  // 18 numbers: written before rolling was tallied.
  if (v.size() != 18 && v.size() != 19)
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
  return p;
}

// The verdict on one frequency from its runs (realisations). With one run the intervals are
// its batch-means intervals; with several, combine_runs() pools them when the runs agree and
// takes the spread of their means when they do not (interval kind 1 and 2). The point is
// converged when every run is stationary and the combined interval meets the tolerance.
struct PointVerdict {
  double size = 0, amplitude_ci = 0, phase = 0, phase_ci = 0;  // m (prescribed: N), rad
  MeanInterval energy;                                         // J per period
  int periods = 0, discarded = 0, interval = 0;
  bool converged = false;
};

PointVerdict judge_point(const std::vector<FrequencyPoint>& runs,
                         const ExcitationSpec& excitation) {
  const SettleSpec& settle = excitation.settle;
  PointVerdict v;
  std::complex<double> mean = 0;
  bool stationary = true;
  for (const FrequencyPoint& p : runs) {
    mean += p.judged.mean / double(runs.size());
    v.periods = std::max(v.periods, p.judged.periods);
    v.discarded = std::max(v.discarded, p.judged.discarded);
    stationary = stationary && !p.judged.trend && p.judged.periods >= settle.min_periods;
  }
  // Amplitudes and phases are combined separately: runs in regimes of different phase would
  // shrink a mean of their complex harmonics below every run's amplitude. Each run's phase is
  // taken about the direction of that mean.
  const std::complex<double> along = std::abs(mean) > 0 ? mean / std::abs(mean) : 1.0;
  std::vector<RunMean> a, q, e;
  for (const FrequencyPoint& p : runs) {
    const int dof = p.judged.batches - 1;
    a.push_back({std::abs(p.judged.mean), p.judged.amplitude_ci, dof});
    q.push_back({std::arg(std::conj(along) * p.judged.mean), p.judged.phase_ci, dof});
    e.push_back({p.energy_in.mean, p.energy_in.half_width, dof});
  }
  // Fills that agree to within about the tolerance are one state for the question asked.
  const double tolerance = settle.tolerance;
  double typical = 0;  // the mean amplitude, the scale of the tolerance
  for (const RunMean& run : a) typical += run.mean / double(a.size());
  const Combined amplitude = combine_runs(a, 0.5 * tolerance * typical);
  const Combined phase = combine_runs(q, 0.5 * tolerance);
  v.energy = combine_runs(e, 0).interval;
  v.size = amplitude.interval.mean, v.amplitude_ci = amplitude.interval.half_width;
  v.phase = std::arg(along * std::polar(1.0, phase.interval.mean));
  v.phase_ci = std::min(kPi, phase.interval.half_width);
  v.interval = runs.size() == 1 ? 0 : amplitude.consistent && phase.consistent ? 1 : 2;
  // A fixed run asked for no tolerance: it is done when every realisation is (frequency_run).
  v.converged = runs.size() == 1 || fixed_duration(excitation)
                    ? std::all_of(runs.begin(), runs.end(),
                                  [](const FrequencyPoint& p) { return p.judged.converged; })
                    : stationary && v.amplitude_ci <= tolerance * v.size && v.phase_ci <= tolerance;
  return v;
}

// One row of /frf or /prescribed (and its /periods) from the runs of one frequency.
void add_row(Results& out, const std::vector<FrequencyPoint>& runs,
             const ExcitationSpec& excitation) {
  const bool prescribed = excitation.kind == ExcitationKind::prescribed;
  const PointVerdict v = judge_point(runs, excitation);
  std::vector<double> rms, dn, dt, dr;
  double peak = 0;
  for (const FrequencyPoint& p : runs) {
    rms.push_back(std::sqrt(p.mean.mean_square));
    peak = std::max(peak, p.mean.peak);
    dn.push_back(p.mean.dissipated_normal);
    dt.push_back(p.mean.dissipated_tangential);
    dr.push_back(p.mean.dissipated_rolling);
  }
  auto average = [](const std::vector<double>& values) {
    double s = 0;
    for (double x : values) s += x;
    return s / double(values.size());
  };
  const double frequency = runs[0].frequency;
  const int realisations = static_cast<int>(runs.size());
  for (std::size_t r = 0; r < runs.size(); ++r)
    for (std::size_t k = 0; k < runs[r].periods.size(); ++k) {
      const PeriodSummary& p = runs[r].periods[k];
      PeriodTable& t = out.periods;
      t.frequency.push_back(frequency);
      t.realisation.push_back(static_cast<int>(r));
      t.period.push_back(static_cast<int>(k));
      t.stationary.push_back(static_cast<int>(k) >= runs[r].judged.discarded ? 1 : 0);
      t.amplitude.push_back(std::abs(p.displacement));
      t.phase.push_back(std::arg(p.displacement));
      t.force_amplitude.push_back(std::abs(p.force));
      t.force_phase.push_back(std::arg(p.force));
      t.energy_in.push_back(p.energy_in);
    }
  if (prescribed) {
    PrescribedTable& p = out.prescribed;
    p.frequency.push_back(frequency);
    p.dissipated_power.push_back(v.energy.mean * frequency);
    p.dissipated_power_ci.push_back(v.energy.half_width * frequency);
    p.force_amplitude.push_back(v.size);
    p.force_amplitude_ci.push_back(v.amplitude_ci);
    p.force_phase.push_back(v.phase);
    p.force_phase_ci.push_back(v.phase_ci);
    p.periods.push_back(v.periods);
    p.periods_discarded.push_back(v.discarded);
    p.converged.push_back(v.converged ? 1 : 0);
    p.realisations.push_back(realisations);
    p.interval.push_back(v.interval);
    return;
  }
  FrfTable& f = out.frf;
  f.frequency.push_back(frequency);
  f.amplitude.push_back(v.size);
  f.amplitude_ci.push_back(v.amplitude_ci);
  f.phase.push_back(v.phase);
  f.phase_ci.push_back(v.phase_ci);
  f.rms.push_back(average(rms));
  f.peak.push_back(peak);
  f.periods.push_back(v.periods);
  f.periods_discarded.push_back(v.discarded);
  f.converged.push_back(v.converged ? 1 : 0);
  f.realisations.push_back(realisations);
  f.interval.push_back(v.interval);
  f.dissipated_energy.push_back(v.energy.mean);
  f.dissipated_energy_ci.push_back(v.energy.half_width);
  f.dissipated_normal.push_back(average(dn));
  f.dissipated_tangential.push_back(average(dt));
  f.dissipated_rolling.push_back(average(dr));
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

// Runs a deck's excitation on one system, or on several side by side: the realisations (fill
// seeds seed + r), or with start = "independent" the frequencies; tasks share the machine's
// cores (`jobs` at a time).
class Driver {
 public:
  Driver(const Deck& deck, std::vector<Scene> scenes, int jobs, bool quiet, std::string dump_path)
      : deck_(deck),
        scenes_(std::move(scenes)),
        jobs_(jobs),
        quiet_(quiet),
        dump_path_(std::move(dump_path)) {
    frequencies_ = scenes_.front().frequencies;
    const std::size_t r = scenes_.size(), f = frequencies_.size();
    points_.assign(r, std::vector<std::optional<FrequencyPoint>>(f));
    beds_.resize(r);
    reports_.resize(r);
  }

  void resume_from(const Results& partial) {
    const StateArrays& c = partial.checkpoint;
    results_.timeseries = partial.timeseries;
    results_.energy = partial.energy;
    results_.particles = partial.particles;
    bed_from_file_ = c.count("bed.from_file") > 0;
    for (std::size_t r = 0; r < scenes_.size(); ++r) {
      beds_[r] = get_state(c, "bed.r" + std::to_string(r) + ".");
      reports_[r] = unpack_report(c, r);
      for (std::size_t i = 0; i < frequencies_.size(); ++i)
        if (const auto it = c.find(point_key(r, i)); it != c.end()) {
          points_[r][i] = unpack(state_values<double>(c, point_key(r, i)));
          unpack_periods(state_values<double>(c, point_key(r, i) + ".periods"), *points_[r][i]);
        }
    }
    for (std::size_t r = 0; r < scenes_.size(); ++r)
      if (StateArrays state = get_state(c, "task.r" + std::to_string(r) + "."); !state.empty())
        task_states_[r] = std::move(state);
    if (independent()) {  // realisation 0's segments, by the frequency each sample was taken at
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
    const ExcitationSpec& x = scenes_.front().excitation;
    if (x.kind == ExcitationKind::free_decay || x.kind == ExcitationKind::sine) {
      Progress progress(quiet_, 1, 1.0, false);
      FrequencyRun run(scenes_[0], [&](double f, double done) { progress.update(0, done, f); });
      try {
        reports_[0] = run.settle_bed();
        if (x.kind == ExcitationKind::free_decay) {
          run.run_free_decay();
        } else {
          points_[0][0] = run.run_frequency(x.frequency, FrequencyStart::carried);
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
  bool independent() const {
    return scenes_.front().excitation.start == FrequencyStart::independent;
  }

  // The /frf (or /prescribed) rows of every frequency all of whose runs have finished, in the
  // order of the frequency list.
  void add_rows(Results& out) const {
    for (std::size_t i = 0; i < frequencies_.size(); ++i) {
      std::vector<FrequencyPoint> runs;
      for (const auto& per_frequency : points_)
        if (per_frequency[i]) runs.push_back(*per_frequency[i]);
      if (runs.size() == points_.size()) add_row(out, runs, scenes_.front().excitation);
    }
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

  // Every realisation's settled bed and its report ("bed.reports": four numbers each), into a
  // checkpoint or a bed file.
  void put_beds(StateArrays& c) const {
    std::vector<double> reports;
    for (std::size_t r = 0; r < scenes_.size(); ++r) {
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

  void settle_beds(Progress& progress) {
    std::vector<std::size_t> missing;
    for (std::size_t r = 0; r < scenes_.size(); ++r)
      if (beds_[r].empty()) missing.push_back(r);
    if (missing.empty()) return;
    const std::string& file = scenes_.front().bed.file;
    const std::string fingerprint = bed_fingerprint(deck_, scenes_[0]);
    if (!file.empty() && std::filesystem::exists(file)) {
      Results saved = read_results(file);
      if (saved.meta_text["bed_fingerprint"] != fingerprint ||
          static_cast<std::size_t>(saved.meta_numbers["realisations"]) < scenes_.size())
        throw InputError(
            deck_.where("bed.file"), "bed.file",
            "'" + file +
                "' holds a bed settled for other particles, container, "
                "contact, gravity, dt or realisations; delete it or name another file");
      for (std::size_t r : missing) {
        beds_[r] = get_state(saved.checkpoint, "bed.r" + std::to_string(r) + ".");
        reports_[r] = unpack_report(saved.checkpoint, r);
      }
      bed_from_file_ = true;
      return;
    }
    in_parallel(missing.size(), [&](std::size_t k) {
      const std::size_t r = missing[k];
      FrequencyRun run(scenes_[r], [&](double f, double done) { progress.update(r, done, f); });
      try {
        reports_[r] = run.settle_bed();
      } catch (const SimulationError& e) {
        fail(run, r, e);
      }
      beds_[r] = run.save();
      std::lock_guard<std::mutex> lock(mutex_);
      Seen from_start;
      account(run, from_start);
    });
    if (!file.empty()) {
      Results saved;
      saved.meta_text["bed_fingerprint"] = fingerprint;
      saved.meta_text["deck"] = deck_.text;
      saved.meta_numbers["realisations"] = double(scenes_.size());
      put_beds(saved.checkpoint);
      write_results(file, saved, true);
    }
  }

  // Runs the frequencies. Realisations run side by side and in step: each frequency's runs are
  // judged together (run_point()) before any goes on. With start = "independent" one task is
  // one frequency, its realisations run in turn, and the tasks run side by side.
  void run_tasks() {
    const std::size_t runs_count = scenes_.size();
    std::vector<std::size_t> todo;  // frequencies with a run still to do
    for (std::size_t i = 0; i < frequencies_.size(); ++i)
      for (std::size_t r = 0; r < runs_count; ++r)
        if (!points_[r][i]) {
          todo.push_back(i);
          break;
        }
    double total = 0;
    for (const auto& per_run : points_)
      for (const auto& point : per_run) total += point ? 0.0 : 1.0;
    const std::size_t lines = independent() ? todo.size() : runs_count;
    Progress progress(quiet_, std::max(lines, runs_count), std::max(total, 1.0),
                      !fixed_duration(scenes_.front().excitation));
    progress_ = &progress;
    settle_beds(progress);
    if (independent()) {
      in_parallel(todo.size(), [&](std::size_t k) {
        const std::size_t i = todo[k];
        double done = 0;
        std::vector<std::unique_ptr<FrequencyRun>> owned(runs_count);
        std::vector<FrequencyRun*> runs(runs_count, nullptr);
        std::vector<Seen> seen(runs_count);
        for (std::size_t r = 0; r < runs_count; ++r) {
          if (points_[r][i]) continue;
          owned[r] = std::make_unique<FrequencyRun>(
              scenes_[r], [&, k](double f, double d) { progress.update(k, done + d, f); });
          owned[r]->restore(beds_[r]);
          runs[r] = owned[r].get();
          seen[r] = {runs[r]->system().particle_steps(), runs[r]->system().time()};
        }
        // Progress: the runs of round 0 done; the later rounds count as the last run's.
        const Each in_turn = [&](std::size_t count, const std::function<void(std::size_t)>& f) {
          for (std::size_t c = 0; c < count; ++c) done = std::max(done, double(c)), f(c);
        };
        finished_points(i, runs, run_point(i, runs, in_turn), seen);
        const auto ran = std::count_if(runs.begin(), runs.end(), [](auto* run) { return run; });
        progress.update(k, double(ran), frequencies_[i]);
      });
    } else {
      std::vector<std::unique_ptr<FrequencyRun>> owned(runs_count);
      std::vector<double> done(runs_count, 0.0);
      std::vector<Seen> seen(runs_count);
      for (std::size_t r = 0; r < runs_count; ++r) {
        owned[r] = std::make_unique<FrequencyRun>(
            scenes_[r], [&, r](double f, double d) { progress.update(r, done[r] + d, f); });
        FrequencyRun& run = *owned[r];
        if (const auto it = task_states_.find(r); it != task_states_.end()) {
          run.restore(it->second);
          if (r == 0) run.set_records(results_.timeseries, results_.energy, results_.particles);
        } else {
          run.restore(beds_[r]);
        }
        seen[r] = {run.system().particle_steps(), run.system().time()};
      }
      const Each side_by_side = [&](std::size_t count, const std::function<void(std::size_t)>& f) {
        in_parallel(count, f);
      };
      for (std::size_t i : todo) {
        std::vector<FrequencyRun*> runs(runs_count, nullptr);
        for (std::size_t r = 0; r < runs_count; ++r)
          if (!points_[r][i]) runs[r] = owned[r].get();
        const std::vector<FrequencyPoint> got = run_point(i, runs, side_by_side);
        for (std::size_t r = 0; r < runs_count; ++r) done[r] += runs[r] ? 1.0 : 0.0;
        finished_points(i, runs, got, seen);
        if (stopped_) break;
      }
    }
    progress.finish();
  }

  // Runs frequency i on the realisations given in `runs` (null where the point is known) and
  // returns every realisation's point. Each run first goes until its own interval is within
  // tolerance x sqrt(R). The point is then judged on all of them (judge_point()): runs that
  // stopped early on narrow intervals of their own can still disagree, when the bed wanders
  // more slowly than their periods showed (Saeki deck, 14 Hz: the phase moves 0.05 rad over
  // 70-period stretches). While the point is not converged and runs have periods left, every
  // run goes on by half the longest run's periods (at least min_periods) and the point is
  // judged again, until the runs' means stop moving (still_moving()). Rounds of whole runs keep the
  // result independent of how the runs are scheduled.
  using Each = std::function<void(std::size_t, const std::function<void(std::size_t)>&)>;
  std::vector<FrequencyPoint> run_point(std::size_t i, const std::vector<FrequencyRun*>& runs,
                                        const Each& each) {
    const ExcitationSpec& x = scenes_.front().excitation;
    std::vector<FrequencyPoint> got(runs.size());
    std::vector<std::size_t> active;
    for (std::size_t r = 0; r < runs.size(); ++r) {
      if (runs[r])
        active.push_back(r);
      else
        got[r] = *points_[r][i];  // from a checkpoint written before the others finished
    }
    auto round = [&](const std::function<FrequencyPoint(std::size_t, FrequencyRun&)>& work) {
      each(active.size(), [&](std::size_t k) {
        const std::size_t r = active[k];
        try {
          got[r] = work(r, *runs[r]);
        } catch (const SimulationError& e) {
          fail(*runs[r], r, e);
        }
      });
    };
    // Each run to its own criterion, then on to the longest one's periods, so that the point is
    // judged on runs of one length. Side by side, a run that is done keeps up with the runs
    // still going instead of waiting for them: the periods it runs are the same either way.
    enum : int { kWaiting, kOnItsOwn, kDone };
    std::vector<std::atomic<int>> stage(runs.size());
    auto longest_going = [&](std::size_t r) {  // -1 when no other run is on its own
      int longest = -1;
      for (std::size_t q : active)
        if (q != r && stage[q] == kOnItsOwn)
          longest = std::max(longest, runs[q]->periods_running());
      return longest;
    };
    round([&](std::size_t r, FrequencyRun& run) {
      stage[r] = kOnItsOwn;
      FrequencyPoint point;
      try {
        point = run.run_frequency(frequencies_[i], x.start);
      } catch (...) {
        stage[r] = kDone;
        throw;
      }
      stage[r] = kDone;
      int periods = point.judged.periods, kept_up = 0;
      for (int target; (target = longest_going(r)) >= 0;) {
        if (g_stop_runs) throw Interrupted();
        if (periods < target && run.periods_left() > 0)
          run.run_period(), ++periods, ++kept_up;
        else
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      return kept_up > 0 ? run.extend(0) : point;  // judged once, on all its periods
    });
    int longest = 0;
    for (std::size_t r : active) longest = std::max(longest, got[r].judged.periods);
    if (std::any_of(active.begin(), active.end(),
                    [&](std::size_t r) { return got[r].judged.periods < longest; }))
      round([&](std::size_t r, FrequencyRun& run) {
        return run.extend(longest - got[r].judged.periods);
      });
    if (fixed_duration(x)) return got;
    std::vector<FrequencyPoint> before;
    for (PointVerdict v = judge_point(got, x); !v.converged; v = judge_point(got, x)) {
      bool left = false;
      for (std::size_t r : active) left = left || runs[r]->periods_left() > 0;
      if (!left) break;
      if (!before.empty() && !still_moving(before, got)) {
        progress_->say("f = " + number(frequencies_[i]) +
                       " Hz: each realisation holds still, apart from the others (fills that "
                       "differ): more periods would not bring them together");
        break;
      }
      const int more = std::max(x.settle.min_periods, v.periods / 2);
      progress_->say(
          "f = " + number(frequencies_[i]) + " Hz: " +
          (v.interval == 2 ? "the realisations disagree" : "not converged over the realisations") +
          "; each runs up to " + std::to_string(more) + " more periods");
      before = got;
      round([&](std::size_t, FrequencyRun& run) { return run.extend(more); });
    }
    return got;
  }

  // Whether a run that ran on is not settled on its own terms (drifting, or its interval too
  // wide) or its mean moved over the new periods by more than its interval: runs that each
  // hold still and still disagree are fills that differ (a spread interval), which more
  // periods would not change.
  static bool still_moving(const std::vector<FrequencyPoint>& before,
                           const std::vector<FrequencyPoint>& after) {
    for (std::size_t r = 0; r < after.size(); ++r) {
      const Stationary &a = before[r].judged, &b = after[r].judged;
      if (b.periods == a.periods) continue;  // it had no periods left
      if (!b.converged || std::fabs(std::abs(b.mean) - std::abs(a.mean)) > b.amplitude_ci ||
          std::fabs(std::arg(b.mean * std::conj(a.mean))) > b.phase_ci)
        return true;
    }
    return false;
  }

  // Records the finished points of frequency i (one per run in `runs`), tells the log, and
  // writes a checkpoint while points remain.
  void finished_points(std::size_t i, const std::vector<FrequencyRun*>& runs,
                       const std::vector<FrequencyPoint>& got, std::vector<Seen>& seen) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++finished_;
    for (std::size_t r = 0; r < runs.size(); ++r) {
      if (!runs[r]) continue;
      const FrequencyRun& run = *runs[r];
      points_[r][i] = got[r];
      account(run, seen[r]);
      if (r == 0) {
        if (independent()) {
          append_segment(run.timeseries(), i);
        } else {
          results_.timeseries = run.timeseries();
          results_.energy = run.energy();
          results_.particles = run.particles();
        }
      }
      progress_->say(describe(got[r], r));
    }
    if (got.size() > 1) {  // the point, as /frf gives it (a run's own verdict is only a part)
      const PointVerdict v = judge_point(got, scenes_.front().excitation);
      std::ostringstream s;
      s.precision(4);
      s << "f = " << frequencies_[i] << " Hz, " << got.size()
        << " realisations: " << amplitude_text(v.size, v.amplitude_ci) << ", phase " << v.phase
        << " +- " << v.phase_ci << " rad" << (v.interval == 2 ? " (their spread)" : "")
        << (v.converged ? ", converged" : ", NOT converged");
      progress_->say(s.str());
    }
    std::size_t remaining = 0;
    for (const auto& per_frequency : points_)
      for (const auto& p : per_frequency) remaining += !p;
    if (remaining == 0 || !checkpoint_) return;
    if (!independent())
      for (std::size_t r = 0; r < runs.size(); ++r)
        if (runs[r]) task_states_[r] = runs[r]->save();
    Results snapshot = results_;
    add_rows(snapshot);  // the finished frequencies are readable (and plottable) in the .partial
    StateArrays& c = snapshot.checkpoint;
    put_beds(c);
    if (bed_from_file_) c["bed.from_file"] = std::vector<std::int32_t>{1};
    for (std::size_t k = 0; k < scenes_.size(); ++k)
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

  // Independent frequencies: realisation 0's time series, one segment per frequency (each from
  // the settled bed's time), kept in the order of the frequency list.
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

  // "0.4605 mm +- 0.25 %" (prescribed motion: "force 1.2 N +- 3 %").
  std::string amplitude_text(double size, double half_width) const {
    std::ostringstream s;
    s.precision(4);
    const bool prescribed = scenes_.front().excitation.kind == ExcitationKind::prescribed;
    s << (prescribed ? "force " : "") << size * (prescribed ? 1.0 : 1e3)
      << (prescribed ? " N" : " mm") << " +- " << 100 * half_width / std::max(size, 1e-300) << " %";
    return s.str();
  }

  std::string describe(const FrequencyPoint& p, std::size_t r) const {
    std::ostringstream s;
    s.precision(4);
    s << "f = " << p.frequency << " Hz";
    if (scenes_.size() > 1) s << " (realisation " << r + 1 << ")";
    s << ": " << amplitude_text(std::abs(p.judged.mean), p.judged.amplitude_ci) << ", "
      << p.judged.periods << " periods (" << p.judged.discarded << " warm-up)";
    if (fixed_duration(scenes_.front().excitation))
      s << ", fixed duration" << (p.judged.converged ? "" : ", " + p.judged.reason);
    else
      s << (p.judged.converged ? ", converged" : ", NOT converged: " + p.judged.reason);
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
    t["coupling"] = schemes[static_cast<int>(scenes_.front().coupling.scheme)];
    const Scene& scene = scenes_[0];
    t["dt_basis"] = scene.dt_basis;
    if (!scene.warning.empty()) t["warning"] = scene.warning;
    const ExcitationKind kind = scenes_.front().excitation.kind;
    if (kind == ExcitationKind::stepped_sine || kind == ExcitationKind::prescribed)
      t["start"] = start_name(scenes_.front().excitation.start);
    const BedReport& bed = reports_[0];
    t["bed"] =
        !bed.ran         ? "not settled (bed.settle = false, or no gravity or particles)"
        : bed_from_file_ ? "read from " + scenes_.front().bed.file
        : bed.settled
            ? "settled in " + number(bed.time_s) + " s"
            : "NOT settled within bed.max_time = " + number(scenes_.front().bed.max_time) + " s";
    n["bed_settled"] = bed.settled ? 1 : 0;
    n["bed_settle_time_s"] = bed.time_s;
    n["bed_speed"] = bed.speed;
    n["realisations"] = double(scenes_.size());
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
  std::vector<Scene> scenes_;  // one per realisation
  int jobs_;
  bool quiet_;
  std::string dump_path_;
  std::vector<double> frequencies_;
  std::vector<std::vector<std::optional<FrequencyPoint>>> points_;  // [realisation][frequency]
  std::vector<StateArrays> beds_;
  std::vector<BedReport> reports_;
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
  std::size_t finished_ = 0;  // frequencies finished in this process
  long long particle_steps_ = 0;
  double simulated_ = 0, wall_ = 0, wall_before_ = 0;
  Clock::time_point started_ = Clock::now();
  std::string backend_, variant_;
  int threads_ = 1;
};

// The frequencies (Hz) whose points did not converge, as a list for the terminal.
// The frequencies whose flag is `value`, comma-separated.
std::string listed(const std::vector<double>& frequency, const std::vector<int>& flag, int value) {
  std::string list;
  for (std::size_t i = 0; i < frequency.size(); ++i)
    if (flag[i] == value) list += (list.empty() ? "" : ", ") + number(frequency[i]);
  return list;
}

// The largest of `value` among converged points (index), or -1 when none converged.
long peak_of(const std::vector<double>& value, const std::vector<int>& converged) {
  long best = -1;
  for (std::size_t i = 0; i < value.size(); ++i)
    if (converged[i] && (best < 0 || value[i] > value[static_cast<std::size_t>(best)]))
      best = static_cast<long>(i);
  return best;
}

std::string summary_line(const Results& r, const std::string& path, const Deck& deck) {
  std::ostringstream s;
  s.precision(4);
  auto tally = [&](const std::vector<double>& frequency, const std::vector<int>& converged,
                   const std::vector<int>& interval, const std::vector<double>& value,
                   const std::vector<double>& ci, double scale, const char* what,
                   const char* unit) {
    int count = 0;
    for (int c : converged) count += c;
    if (fixed_duration(deck.excitation)) {  // no steady state was asked for: say what it shows
      s << frequency.size() << (frequency.size() == 1 ? " frequency" : " frequencies") << ", "
        << deck.excitation.duration << " s each";
      const long k = peak_of(value, std::vector<int>(frequency.size(), 1));
      s << "; " << (frequency.size() == 1 ? "" : "peak ") << what << " "
        << scale * value[std::size_t(k)] << " +- " << scale * ci[std::size_t(k)] << " " << unit
        << " at " << frequency[std::size_t(k)] << " Hz";
      if (count < static_cast<int>(frequency.size()))
        s << "; drifting or too short for an interval at " << listed(frequency, converged, 0)
          << " Hz (run longer)";
      return;
    }
    s << frequency.size() << " frequencies, " << count << " converged";
    const long k = peak_of(value, converged);
    if (k >= 0)
      s << "; peak " << what << " " << scale * value[std::size_t(k)] << " +- "
        << scale * ci[std::size_t(k)] << " " << unit << " at " << frequency[std::size_t(k)]
        << " Hz (of the converged points)";
    if (count < static_cast<int>(frequency.size()))
      s << "; NOT converged at " << listed(frequency, converged, 0)
        << " Hz: not results (give them more settle.max_periods, a looser settle.tolerance or "
           "more settle.realisations)";
    const std::string disagree = listed(frequency, interval, 2);
    if (!disagree.empty())
      s << "; the realisations disagree at " << disagree
        << " Hz (coexisting regimes of the bed: the interval is the spread of their means)";
  };
  if (!r.frf.frequency.empty() && deck.excitation.kind == ExcitationKind::stepped_sine) {
    s << "FRF: ";
    tally(r.frf.frequency, r.frf.converged, r.frf.interval, r.frf.amplitude, r.frf.amplitude_ci,
          1e3, "amplitude", "mm");
  } else if (!r.frf.frequency.empty()) {
    s << "sine at " << r.frf.frequency[0] << " Hz: first harmonic " << 1e3 * r.frf.amplitude[0]
      << " +- " << 1e3 * r.frf.amplitude_ci[0] << " mm"
      << (r.frf.converged[0] ? "" : " (not stationary over the duration)");
  } else if (!r.prescribed.frequency.empty()) {
    s << "prescribed motion: ";
    tally(r.prescribed.frequency, r.prescribed.converged, r.prescribed.interval,
          r.prescribed.dissipated_power, r.prescribed.dissipated_power_ci, 1.0, "power", "W");
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

// The scene of every realisation (fill seeds seed + r of every damper) and how many runs go side
// by side: one per core unless told, the cores shared out among them.
struct Plan {
  std::vector<Scene> scenes;
  int jobs = 1;
};

Plan plan_run(const Deck& deck, const Scene& scene, int threads, int jobs,
              std::optional<Backend> backend) {
  const ExcitationSpec& x = deck.excitation;
  const bool swept = x.kind == ExcitationKind::stepped_sine || x.kind == ExcitationKind::prescribed;
  const int realisations = swept ? x.settle.realisations : 1;
  // Side by side: the realisations, or with independent frequencies the frequencies (each task
  // runs its realisations in turn, Driver::run_tasks()).
  const int tasks = swept && x.start == FrequencyStart::independent
                        ? static_cast<int>(x.frequencies.size())
                        : realisations;
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int total = threads > 0 ? threads : deck.solver.threads > 0 ? deck.solver.threads : cores;
  Plan plan;
  plan.jobs = std::max(1, std::min(tasks, jobs > 0 ? jobs : total));
  const int each = tasks > 1 ? std::max(1, total / plan.jobs) : threads;
  for (int r = 0; r < realisations; ++r) {
    Deck seeded = deck;
    for (DamperSpec& d : seeded.dampers) d.particles.seed += static_cast<std::uint64_t>(r);
    plan.scenes.push_back(r == 0 && each == threads ? scene : build_scene(seeded, each, backend));
  }
  return plan;
}

}  // namespace

Results simulate(const Deck& deck, const Scene& scene, bool quiet, int jobs) {
  Plan plan = plan_run(deck, scene, scene.threads, jobs, std::nullopt);
  Driver driver(deck, std::move(plan.scenes), plan.jobs, quiet, "");
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
  Driver driver(deck, std::move(plan.scenes), plan.jobs, options.quiet, path + ".blowup.csv");
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
      << " batches, " << settle.realisations << " realisation"
      << (settle.realisations > 1 ? "s" : "") << ")\n";
  if (deck.bed.settle)
    s << "bed: settled under gravity first, until no particle moves faster than " << deck.bed.speed
      << " m/s for " << kBedHold_s << " s (at most " << deck.bed.max_time << " s)"
      << (deck.bed.file.empty() ? "" : "; kept in " + deck.bed.file) << "\n";
  // Estimated cost: simulated time x steps/s x particles, at an assumed 1e7 particle-steps/s.
  double simulated = 0;
  if (judged)
    for (double f :
         (x.frequencies.empty() ? std::vector<double>{x.motion.frequency} : x.frequencies))
      simulated += settle.realisations * settle.max_periods / f;
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
