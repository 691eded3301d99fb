#include "src/driver.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>
#include <utility>

#include "src/format.hpp"
#include "src/frequency_run.hpp"
#include "src/identity.hpp"
#include "src/interrupt.hpp"
#include "src/point_checkpoint.hpp"
#include "src/point_rows.hpp"
#include "src/progress.hpp"

namespace pdsim {

class Driver::Impl {
 public:
  Impl(DeckRecord deck, RunPlan plan, std::optional<Results> kept_beds, Scene first,
       SceneMaker make_scene, int jobs, bool quiet, std::string dump_path)
      : deck_(std::move(deck)),
        plan_(std::move(plan)),
        kept_beds_(std::move(kept_beds)),
        make_scene_(std::move(make_scene)),
        jobs_(jobs),
        quiet_(quiet),
        dump_path_(std::move(dump_path)) {
    fills_min_ = plan_.first_fills;
    fills_max_ = plan_.most_fills;
    const auto fills = static_cast<std::size_t>(fills_max_), steps = plan_.points.size();
    scenes_.resize(fills);
    scenes_[0] = std::make_unique<Scene>(std::move(first));
    identity_ = identity_text(scene_identity(*scenes_[0], plan_.bed));
    points_.assign(fills, std::vector<std::optional<FrequencyPoint>>(steps));
    done_.assign(steps, 0);
    beds_.resize(fills);
    reports_.resize(fills);
    runs_.resize(fills);
    reached_.assign(fills, -1);
    looks_.assign(fills, std::vector<std::vector<std::complex<double>>>(steps));
    look_at_.assign(fills, 0);
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
      for (std::size_t i = 0; i < plan_.points.size(); ++i)
        if (const auto it = c.find(point_key(r, i)); it != c.end()) {
          points_[r][i] = unpack(state_values<double>(c, point_key(r, i)));
          unpack_periods(state_values<double>(c, point_key(r, i) + ".periods"), *points_[r][i]);
          if (c.count(point_key(r, i) + ".looks") > 0) {
            const auto& v = state_values<double>(c, point_key(r, i) + ".looks");
            for (std::size_t j = 0; j + 1 < v.size(); j += 2)
              looks_[r][i].emplace_back(v[j], v[j + 1]);
          }
          reached_[r] = static_cast<long>(i);
        }
      if (StateArrays state = get_state(c, "task.r" + std::to_string(r) + "."); !state.empty())
        task_states_[r] = std::move(state);
    }
    if (independent()) {  // fill 0's segments, by the frequency each sample was taken at
      const TimeSeries& ts = partial.timeseries;
      for (std::size_t j = 0; j < ts.frequency.size(); ++j) {
        const auto& points = plan_.points;
        const auto at = std::find_if(points.begin(), points.end(), [&](const PlanPoint& p) {
          return p.frequency == ts.frequency[j];
        });
        if (at == points.end()) continue;
        TimeSeries& segment = segments_[static_cast<std::size_t>(at - points.begin())];
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
    simulated_start_ = simulated_;
    clear_stop();  // an interrupt before the start stops it at once
    checkpoint_ = checkpoint;
    stop_after_ = stop_after;
    run_tasks();
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
  bool independent() const { return plan_.independent(); }
  bool prescribed() const { return plan_.prescribed; }
  const PlanPoint& planned(std::size_t s) const { return plan_.points[s]; }

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
    if (!plan_.harmonics) return {};  // nothing to judge: done once run
    std::vector<FrequencyPoint> runs;
    for (const auto& [r, p] : fills_at(s))
      if (static_cast<std::size_t>(r) < count) runs.push_back(p);
    return judge_fills(runs, plan_);
  }

  // The /frf (or /prescribed) rows of every finished point, in the order they are run.
  void add_rows(Results& out) const {
    if (!plan_.harmonics) return;
    for (std::size_t s = 0; s < plan_.points.size(); ++s)
      if (done_[s]) add_row(out, fills_at(s), planned(s).sweep, planned(s).amplitude, plan_);
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
      for (std::size_t k; (k = next++) < count && !stop_requested();) {
        try {
          work(k);
        } catch (...) {
          std::lock_guard<std::mutex> lock(failure_mutex);
          if (!failure && !stopped_) failure = std::current_exception();
          request_stop();
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
    if (stop_requested() && !stopped_) throw Interrupted();
  }

  // Dumps the particles of a failed run beside the output and says where.
  // Also keeps what the failed run computed (its time series up to the failure, the finished
  // frequencies) for failed(): a run that blows up in its only segment would otherwise leave
  // nothing but the particle dump.
  [[noreturn]] void fail(const FrequencyRun& run, std::size_t r, const SimulationError& e) {
    if (interrupted() || dump_path_.empty() || dynamic_cast<const Interrupted*>(&e)) throw;
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
    const std::string& file = plan_.bed.file;
    if (std::optional<Results> saved = std::exchange(kept_beds_, std::nullopt)) {
      const auto held = static_cast<std::size_t>(saved->meta_numbers["realisations"]);
      for (std::size_t r = 0; r < std::min(held, beds_.size()); ++r)
        if (beds_[r].empty()) {
          beds_[r] = get_state(saved->checkpoint, "bed.r" + std::to_string(r) + ".");
          reports_[r] = unpack_report(saved->checkpoint, r);
        }
      bed_from_file_ = true;
      return;
    }
    in_parallel(missing.size(), [&](std::size_t k) { settle_bed(missing[k], progress); });
    if (!file.empty()) {
      Results saved;
      saved.meta_text["identity"] = identity_;
      saved.meta_text["deck"] = deck_.text;
      saved.meta_numbers["realisations"] = double(first);
      put_beds(saved.checkpoint, first);
      write_results(file, saved, true);
    }
  }
  void settle_bed(std::size_t r, Progress& progress) {
    FrequencyRun run(scene(r), plan_, [&](double f, double done) { progress.update(r, done, f); });
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
    // Progress: a slot per fill (carried: the points it has run, resumed ones included) or per
    // point (independent: its fills run in this session); the first fills' work, to which
    // fills added later add theirs.
    const std::size_t slots = independent() ? plan_.points.size() : beds_.size();
    const double total =
        independent() ? double(todo) * fills_min_ : double(plan_.points.size()) * fills_min_;
    Progress progress(quiet_, std::max(slots, beds_.size()), std::max(total, 1.0), plan_.steady);
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
    const double tolerance = plan_.settle.tolerance;
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
    for (const PlanPoint& p : plan_.points) both = both || p.sweep != planned(0).sweep;
    const PlanPoint& p = planned(s);
    const std::string amplitude =
        plan_.amplitude_steps ? ", amplitude " + number(p.amplitude) + (prescribed() ? " m" : "")
                              : "";
    return "f = " + number(p.frequency) + " Hz" + amplitude +
           (both ? (p.sweep > 0 ? " (up)" : " (down)") : "");
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
    const auto last = static_cast<long>(plan_.points.size()) - 1;
    want_.assign(plan_.points.size(), fills_min_);
    target_.assign(beds_.size(), -1);
    busy_.assign(beds_.size(), 0);
    for (std::size_t r = 0; r < static_cast<std::size_t>(fills_min_); ++r) target_[r] = last;
    std::unique_lock<std::mutex> lock(mutex_);
    judge_ready();
    std::exception_ptr failure;
    std::condition_variable& changed = changed_;
    auto worker = [&] {
      std::unique_lock<std::mutex> held(mutex_);
      for (;;) {
        if (stop_requested()) return;
        // The fill furthest behind first: points then finish about in order.
        std::size_t pick = beds_.size();
        bool running = false, paused = false;
        for (std::size_t r = 0; r < beds_.size(); ++r) {
          running = running || busy_[r];
          if (busy_[r] || reached_[r] >= target_[r]) continue;
          // A fill paused at a look goes on once the fills it compares with have got there.
          if (look_at_[r] > 0 && look_values(r).empty()) {
            paused = true;
            continue;
          }
          if (pick == beds_.size() || reached_[r] < reached_[pick]) pick = r;
        }
        if (pick == beds_.size()) {
          // A fill waits only for fills before it, which never wait for it: a pause ends.
          if (!running && paused && !failure) {
            failure =
                std::make_exception_ptr(SimulationError("fills wait for each other at a look"));
            request_stop();
          }
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
          request_stop();
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
    if (stop_requested() && !stopped_) throw Interrupted();
  }

  // The simulated time (s) that the points still planned are expected to take (mutex_ held),
  // for the progress line's ETA: every fill's points up to its target, and the fills that the
  // points not yet judged are expected to add (each catching up from where it is). A fill's
  // cost at a point is the mean of the fills that ran it, or before any did, that of the
  // finished points of the nearest amplitude, the point's amplitude predicted from fill 0's
  // last point (the equivalent-linear model of the predicted start): near resonance, where
  // the amplitude is large, fills need more periods and points more fills, on either side.
  double planned_remaining() const {
    struct Measured {
      double amplitude = 0, periods = 0;
      int fills = 0;
    };
    const std::size_t points = plan_.points.size();
    std::vector<Measured> seen(points);
    std::vector<std::pair<double, std::size_t>> finished;  // (amplitude, point), judged points
    for (std::size_t s = 0; s < points; ++s) {
      for (std::size_t r = 0; r < points_.size(); ++r)
        if (const auto& p = points_[r][s]) {
          seen[s].amplitude += std::abs(p->judged.mean);
          seen[s].periods += p->judged.periods;
          ++seen[s].fills;
        }
      if (seen[s].fills > 0) {
        seen[s].amplitude /= seen[s].fills;
        seen[s].periods /= seen[s].fills;
      }
      if (done_[s]) finished.emplace_back(seen[s].amplitude, s);
    }
    std::sort(finished.begin(), finished.end());
    // A finished point's (periods a fill, fills) interpolated at `amplitude`, in its logarithm;
    // above every finished point, nearer resonance than any yet: every fill, each with the
    // periods of the highest point. (Replayed on the Saeki example's log, growing the periods
    // with the amplitude as below it overshot the remaining time 2-3 fold, keeping the fills of
    // the highest point fell 50 % short; this was within 10 %.)
    auto learned = [&](double amplitude) -> std::pair<double, double> {
      if (finished.empty())  // not called before a point has finished (judge_ready())
        return {double(plan_.settle.max_periods), double(fills_max_)};
      auto at = [&](std::size_t k) {
        const std::size_t s = finished[k].second;
        return std::pair<double, double>{seen[s].periods, double(want_[s])};
      };
      const auto above = std::lower_bound(finished.begin(), finished.end(),
                                          std::make_pair(amplitude, std::size_t(0)));
      if (above == finished.begin()) return at(0);
      if (above == finished.end()) return {at(finished.size() - 1).first, double(fills_max_)};
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
      if (points_[0][s] && !points_[0][s]->mean.container.empty()) last = &*points_[0][s];
    auto predicted = [&](std::size_t s) {
      const Scene& scene = *scenes_[0];
      if (!last || !scene.structure || last->frequency <= 0) return 0.0;
      const double w0 = 2 * kPi * last->frequency, w = 2 * kPi * planned(s).frequency;
      std::vector<std::complex<double>> impedance;
      for (std::size_t k = 0; k < last->mean.container.size(); ++k) {
        const std::complex<double> u = last->mean.container[k];
        const std::complex<double> z = std::abs(u) > 0 ? -last->mean.damper_force[k] / u : 0.0;
        impedance.emplace_back(z.real() / (w0 * w0) * w * w, z.imag() / w0 * w);
      }
      const DrivePhasors drive =
          drive_phasors(*scene.structure, plan_.input, planned(s).amplitude, w);
      return std::abs((scene.structure->response.cast<std::complex<double>>() *
                       harmonic_response(*scene.structure, w, drive.load, impedance, drive.base))
                          .value());
    };
    std::vector<double> cost(points);  // simulated seconds a fill
    std::vector<int> fills(points);    // fills each point is expected to end with
    for (std::size_t s = 0; s < points; ++s) {
      const auto [periods, wanted] = seen[s].fills > 0
                                         ? std::pair<double, double>{seen[s].periods, 0.0}
                                         : learned(predicted(s));
      const double f = planned(s).frequency > 0 ? planned(s).frequency : 1.0;
      cost[s] = periods / f;
      const double expected = seen[s].fills > 0 ? learned(seen[s].amplitude).second : wanted;
      fills[s] = done_[s]
                     ? want_[s]
                     : std::clamp(static_cast<int>(std::lround(expected)), want_[s], fills_max_);
    }
    double remaining = 0;
    std::vector<long> reach(target_);  // each fill's last point, as planned so far
    for (std::size_t r = 0; r < reach.size(); ++r)
      for (long s = reached_[r] + 1; s <= reach[r]; ++s) remaining += cost[std::size_t(s)];
    for (std::size_t s = 0; s < points; ++s)
      for (auto r = std::size_t(want_[s]); !done_[s] && r < std::size_t(fills[s]); ++r)
        for (; reach[r] < static_cast<long>(s); ++reach[r])
          remaining += cost[std::size_t(reach[r] + 1)];
    return remaining;
  }

  // Judges every point whose wanted fills have all run it (mutex_ held): finished, or more
  // fills sent to it.
  void judge_ready() {
    for (std::size_t s = 0; s < plan_.points.size(); ++s) {
      if (done_[s]) continue;
      bool ready = true;
      for (std::size_t r = 0; r < static_cast<std::size_t>(want_[s]); ++r)
        ready = ready && points_[r][s].has_value();
      if (!ready) continue;
      const Ensemble e = judge_step(s, static_cast<std::size_t>(want_[s]));
      if (e.wants_fills && want_[s] < fills_max_) {
        const int next = more_fills(e, want_[s]);
        say_adding(s, e, want_[s], next);
        for (auto r = static_cast<std::size_t>(want_[s]); r < static_cast<std::size_t>(next); ++r) {
          if (target_[r] < static_cast<long>(s))
            progress_->add_total(double(static_cast<long>(s) - target_[r]));
          target_[r] = std::max(target_[r], static_cast<long>(s));
        }
        want_[s] = next;
        continue;
      }
      finished_step(s);
      if (stopped_) return;
    }
    // The model learns from finished points: before the first, it knows no point's cost (it
    // took min_periods for each, and the running point overtook that: "100 %, ETA 0 s" for
    // minutes), so the line says "ETA after the first frequency" until one is done.
    if (plan_.steady && std::any_of(done_.begin(), done_.end(), [](char d) { return d != 0; }))
      progress_->set_work(simulated_ - simulated_start_, planned_remaining());
  }

  // Runs fill r's next point (a fill's first from its settled bed) and records it.
  void run_next_point(std::size_t r, Progress& progress) {
    if (!runs_[r]) {
      ensure_bed(r, progress);
      std::lock_guard<std::mutex> lock(mutex_);  // task_states_ and results_ are shared
      runs_[r] =
          std::make_unique<FrequencyRun>(scene(r), plan_, [this, r, &progress](double f, double d) {
            // d is the point's periods over max_periods (FrequencyRun::run_period())
            progress.update(r, double(reached_[r] + 1) + d, f,
                            f > 0 ? d * plan_.settle.max_periods / f : 0.0);
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
      if (!looking())
        point = run.run_point(planned(k).frequency, planned(k).amplitude);
      else if (run_with_looks(run, r, k))
        point = run.finish();
      else
        return;  // paused at a look
    } catch (const SimulationError& e) {
      fail(run, r, e);
    }
    // The fill's state, for a resume, while it has points left.
    const bool more = k + 1 < plan_.points.size();
    StateArrays state = checkpoint_ && more ? run.save() : StateArrays{};
    std::lock_guard<std::mutex> lock(mutex_);
    points_[r][k] = std::move(point);
    reached_[r] = static_cast<long>(k);
    if (checkpoint_ && more) task_states_[r] = std::move(state);
    account(run, seen_[r]);
    if (r == 0) {
      results_.timeseries = run.timeseries();
      results_.energy = run.energy();
      results_.particles = run.particles();
    }
    progress_->update(r, double(k + 1), planned(k).frequency,
                      0.0);  // its time is in simulated_ now
    const bool catching_up = r >= static_cast<std::size_t>(want_[k]);
    progress_->say(describe(*points_[r][k], r) + (catching_up ? " (catching up)" : ""));
  }

  // A carried sweep's fills look at each other every kLookPeriods periods of a point: a fill
  // whose own interval is small beside the fills' spread (spread_floors()) stops there, since
  // more of its periods would not narrow the ensemble mean's interval and another fill does.
  // Fill r compares its mean with those of the fills before it (or of all the first fills,
  // settle.realisations) at the same look, or their final ones where they finished the point
  // before it, so that no decision depends on the schedule. Every fill before r runs every
  // point r runs (fills are added in order, each up to the last point that wants it), so a
  // look waits only for fills before it, and the first fills for each other. Every 25
  // periods: a tenth of the longest climbs after a step, a few seconds of a core on the Saeki
  // deck.
  static constexpr int kLookPeriods = 25;
  bool looking() const {
    return !independent() && fills_min_ >= 2 && plan_.steady && plan_.settle.average_periods == 0;
  }
  // The means fill r's pending look compares (mutex_ held): its own and those of the fills
  // before it at that look, or their final ones; empty while one has not got there.
  std::vector<std::complex<double>> look_values(std::size_t r) const {
    const auto s = static_cast<std::size_t>(reached_[r] + 1), j = std::size_t(look_at_[r]);
    std::vector<std::complex<double>> values;
    for (std::size_t q = 0; q < std::max(r + 1, static_cast<std::size_t>(fills_min_)); ++q) {
      const auto& posted = looks_[q][s];
      if (posted.size() >= j)
        values.push_back(posted[j - 1]);
      else if (points_[q][s])
        values.push_back(points_[q][s]->judged.mean);
      else
        return {};
    }
    return values;
  }
  // Runs fill r's point k on from where it paused: true when it is done, false when a look
  // waits for the first fills.
  bool run_with_looks(FrequencyRun& run, std::size_t r, std::size_t k) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (look_at_[r] == 0) {
      looks_[r][k].clear();  // a point run again after a resume posts the same means again
      lock.unlock();
      run.begin_point(planned(k).frequency, planned(k).amplitude);
      lock.lock();
    }
    for (;;) {
      if (look_at_[r] > 0) {
        const std::vector<std::complex<double>> values = look_values(r);
        if (values.empty()) return false;
        lock.unlock();
        const bool done = run.look(spread_floors(values));
        lock.lock();
        if (done) break;
      }
      const int next = (look_at_[r] + 1) * kLookPeriods;
      lock.unlock();
      const bool done = run.run_until(next);
      const std::complex<double> mean = done ? 0.0 : run.judge().mean;
      lock.lock();
      if (done) break;
      looks_[r][k].push_back(mean);
      ++look_at_[r];
      changed_.notify_all();  // a fill paused at this look may go on
    }
    look_at_[r] = 0;
    return true;
  }

  // Independent points side by side, each point's fills in turn from their settled beds.
  void run_independent(Progress& progress) {
    std::vector<std::size_t> todo;
    for (std::size_t s = 0; s < plan_.points.size(); ++s)
      if (!done_[s]) todo.push_back(s);
    in_parallel(todo.size(), [&](std::size_t k) {
      const std::size_t s = todo[k];
      double done = 0;
      for (int want = fills_min_;;) {
        for (std::size_t r = 0; r < static_cast<std::size_t>(want); ++r, done += 1) {
          if (points_[r][s]) continue;
          ensure_bed(r, progress);
          FrequencyRun run(scene(r), plan_,
                           [&, k](double f, double d) { progress.update(k, done + d, f); });
          run.restore(beds_[r]);
          Seen seen{run.system().particle_steps(), run.system().time()};
          FrequencyPoint point;
          try {
            point = run.run_point(planned(s).frequency, planned(s).amplitude);
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
        progress_->add_total(next - want);
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
    if (plan_.harmonics)
      progress_->say(point_name(s) + ": " + ensemble_text(judge_step(s), prescribed()));
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
      for (std::size_t f = 0; f < plan_.points.size(); ++f)
        if (points_[k][f]) {
          c[point_key(k, f)] = pack(*points_[k][f]);
          c[point_key(k, f) + ".periods"] = pack_periods(*points_[k][f]);
          if (!looks_[k][f].empty()) {
            std::vector<double> looks;
            for (const auto& h : looks_[k][f]) looks.insert(looks.end(), {h.real(), h.imag()});
            c[point_key(k, f) + ".looks"] = std::move(looks);
          }
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
      request_stop();
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
    if (!plan_.harmonics)
      return "free decay from " + number(plan_.initial_displacement) +
             " m: " + number(plan_.duration) + " s";
    std::ostringstream s;
    s.precision(4);
    s << "f = " << p.frequency << " Hz";
    if (fills_max_ > 1) s << " (fill " << r + 1 << ")";
    s << ": " << amplitude_text(std::abs(p.judged.mean), p.judged.amplitude_ci, prescribed())
      << ", " << p.judged.periods << " periods (" << p.judged.discarded << " warm-up)";
    if (plan_.fixed)
      s << ", fixed duration" << (p.judged.converged ? "" : ", " + p.judged.reason);
    else
      s << (p.judged.by_spread   ? ", settled to a third of the fills' spread"
            : p.judged.converged ? ", settled"
            : settled(p.judged)  ? ", held still (" + p.judged.reason + ")"
                                 : ", NOT settled: " + p.judged.reason);
    return s.str();
  }

  void provenance(Results& r) const {
    RunFacts f;
    f.scene = scenes_[0].get();
    f.plan = &plan_;
    f.identity = identity_;
    f.backend = backend_;
    f.variant = variant_;
    f.bed = reports_[0];
    f.bed_from_file = bed_from_file_;
    f.fills_min = fills_min_;
    f.fills_max = fills_max_;
    for (std::size_t k = 0; k < points_.size(); ++k)
      for (const auto& p : points_[k])
        f.fills_used = p ? std::max(f.fills_used, k + 1) : f.fills_used;
    f.jobs = jobs_;
    f.threads = threads_;
    f.wall_s = wall_;
    f.simulated_s = simulated_;
    f.particle_steps = particle_steps_;
    f.solver_start = solver_start_;
    write_provenance(r, deck_, f);
  }

  const DeckRecord deck_;
  const RunPlan plan_;                // every fill's FrequencyRun reads it
  std::string identity_;              // fill 0's scene's (src/identity.hpp), taken once
  std::optional<Results> kept_beds_;  // read from bed.file before the run (read_bed_file())
  SceneMaker make_scene_;
  std::vector<std::unique_ptr<Scene>> scenes_;  // one per fill, built when first needed
  std::mutex scene_mutex_;
  int jobs_;
  bool quiet_;
  std::string dump_path_;
  int fills_min_ = 1, fills_max_ = 1;
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
  // carried: each fill's means at its looks, per point, and the look it is paused at (0: none)
  std::vector<std::vector<std::vector<std::complex<double>>>> looks_;
  std::vector<int> look_at_;
  std::condition_variable changed_;  // carried: a fill finished a point, paused or posted a look
  std::vector<Seen> seen_;
  std::map<std::size_t, StateArrays> task_states_;
  std::map<std::size_t, TimeSeries> segments_;
  Results results_;
  std::function<void(const Results&)> checkpoint_;
  Progress* progress_ = nullptr;
  SolverTotals solver_start_ = nonsmooth_totals();  // the non-smooth solves before this run
  std::mutex mutex_;
  int stop_after_ = 0;
  std::atomic<bool> stopped_{false};
  bool bed_from_file_ = false;
  std::optional<Results> failed_;
  std::size_t finished_ = 0;  // points finished in this process
  long long particle_steps_ = 0;
  double simulated_ = 0, wall_ = 0, wall_before_ = 0;
  double simulated_start_ = 0;  // of this session (a resumed run's earlier work aside)
  Clock::time_point started_ = Clock::now();
  std::string backend_, variant_;
  int threads_ = 1;
};

Driver::Driver(DeckRecord deck, RunPlan plan, std::optional<Results> kept_beds, Scene first,
               SceneMaker make_scene, int jobs, bool quiet, std::string dump_path)
    : impl_(std::make_unique<Impl>(std::move(deck), std::move(plan), std::move(kept_beds),
                                   std::move(first), std::move(make_scene), jobs, quiet,
                                   std::move(dump_path))) {}
Driver::~Driver() = default;
void Driver::resume_from(const Results& partial) {
  impl_->resume_from(partial);
}
Results Driver::run(const std::function<void(const Results&)>& checkpoint, int stop_after) {
  return impl_->run(checkpoint, stop_after);
}
bool Driver::stopped() const {
  return impl_->stopped();
}
const Results* Driver::failed() const {
  return impl_->failed();
}
std::size_t Driver::finished() const {
  return impl_->finished();
}

}  // namespace pdsim
