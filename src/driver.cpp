#include "src/driver.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>
#include <utility>

#include "src/frequency_run.hpp"
#include "src/identity.hpp"
#include "src/interrupt.hpp"
#include "src/point_policy.hpp"
#include "src/point_rows.hpp"
#include "src/progress.hpp"
#include "src/run_record.hpp"

namespace pdsim {

class Driver::Impl {
 public:
  Impl(DeckRecord deck, RunPlan plan, std::optional<Results> kept_beds, Scene first,
       SceneMaker make_scene, int jobs, bool quiet, std::string dump_path)
      : deck_(std::move(deck)),
        plan_(std::move(plan)),
        record_(static_cast<std::size_t>(plan_.most_fills), plan_.points.size()),
        kept_beds_(std::move(kept_beds)),
        make_scene_(std::move(make_scene)),
        jobs_(jobs),
        quiet_(quiet),
        dump_path_(std::move(dump_path)) {
    const auto fills = static_cast<std::size_t>(plan_.most_fills);
    scenes_.resize(fills);
    scenes_[0] = std::make_unique<Scene>(std::move(first));
    identity_ = identity_text(scene_identity(*scenes_[0], plan_.bed));
    runs_.resize(fills);
    reached_.assign(fills, -1);
    look_at_.assign(fills, 0);
    seen_.resize(fills);
    bed_once_ = std::make_unique<std::once_flag[]>(fills);
  }

  void resume_from(const Results& partial) {
    results_.timeseries = partial.timeseries;
    results_.energy = partial.energy;
    results_.particles = partial.particles;
    get_checkpoint(partial.checkpoint, record_);
    for (std::size_t r = 0; r < reached_.size(); ++r) reached_[r] = record_.reached(r);
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
  }

  Results run(const std::function<void(const Results&)>& checkpoint, int stop_after) {
    started_ = Clock::now();
    simulated_start_ = record_.simulated_s;
    clear_stop();  // an interrupt before the start stops it at once
    checkpoint_ = checkpoint;
    stop_after_ = stop_after;
    run_tasks();
    if (!stopped_) add_rows(results_);
    wall_ = record_.wall_before_s + std::chrono::duration<double>(Clock::now() - started_).count();
    provenance(results_);
    return results_;
  }

  bool stopped() const { return stopped_; }
  // What a failed run had computed, or nullptr (see fail()).
  const Results* failed() const { return failed_ ? &*failed_ : nullptr; }
  std::size_t finished() const { return finished_; }

 private:
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
    for (std::size_t r = 0; r < record_.points.size(); ++r)
      if (record_.points[r][s]) fills.emplace_back(static_cast<int>(r), *record_.points[r][s]);
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
      if (record_.done[s]) add_row(out, fills_at(s), planned(s).sweep, planned(s).amplitude, plan_);
  }

  // Adds what `run` did since `seen` (its particle steps and simulated time) to the totals.
  struct Seen {
    long long steps = 0;
    double time = 0;
  };
  void account(const FrequencyRun& run, Seen& seen) {
    record_.particle_steps += run.system().particle_steps() - seen.steps;
    record_.simulated_s += run.system().time() - seen.time;
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

  // The beds of the first fills (settle.realisations): from bed.file when it holds them (with
  // any further fills it holds), else settled side by side (and written there).
  void settle_beds(Progress& progress) {
    const auto first = static_cast<std::size_t>(plan_.first_fills);
    std::vector<std::size_t> missing;
    for (std::size_t r = 0; r < first; ++r)
      if (record_.beds[r].empty()) missing.push_back(r);
    if (missing.empty()) return;
    const std::string& file = plan_.bed.file;
    if (std::optional<Results> saved = std::exchange(kept_beds_, std::nullopt)) {
      get_beds(saved->checkpoint, static_cast<std::size_t>(saved->meta_numbers["realisations"]),
               record_);
      record_.bed_from_file = true;
      return;
    }
    in_parallel(missing.size(), [&](std::size_t k) { settle_bed(missing[k], progress); });
    if (!file.empty()) {
      Results saved;
      saved.meta_text["identity"] = identity_;
      saved.meta_text["deck"] = deck_.text;
      saved.meta_numbers["realisations"] = double(first);
      put_beds(record_, first, saved.checkpoint);
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
    record_.reports[r] = report;
    record_.beds[r] = run.save();
    Seen from_start;
    account(run, from_start);
  }
  // Fill r's bed, settled the first time a fill beyond the first ones needs it.
  void ensure_bed(std::size_t r, Progress& progress) {
    std::call_once(bed_once_[r], [&] {
      if (record_.beds[r].empty()) settle_bed(r, progress);
    });
  }

  void run_tasks() {
    std::size_t todo = 0;
    for (char d : record_.done) todo += d ? 0 : 1;
    // Progress: a slot per fill (carried: the points it has run, resumed ones included) or per
    // point (independent: its fills run in this session); the first fills' work, to which
    // fills added later add theirs.
    const std::size_t slots = independent() ? plan_.points.size() : record_.beds.size();
    const double total = independent() ? double(todo) * plan_.first_fills
                                       : double(plan_.points.size()) * plan_.first_fills;
    Progress progress(quiet_, std::max(slots, record_.beds.size()), std::max(total, 1.0),
                      plan_.steady);
    progress_ = &progress;
    settle_beds(progress);
    if (independent())
      run_independent(progress);
    else
      run_carried(progress);
    progress.finish();
  }

  void say_adding(std::size_t s, const Ensemble& e, int now, int next) {
    progress_->say(point_text(plan_, s) + ": " + ensemble_text(e, prescribed()) + "; " +
                   std::to_string(next - now) + " more fills (" + std::to_string(next) + " of " +
                   std::to_string(plan_.most_fills) + ")");
  }

  // A carried sweep. Every fill is a sweep of its own, so fills run independently, `jobs_` at
  // a time: the first fills (settle.realisations) through every point; a point is judged once
  // each fill it wants has run it, and when it wants more, fills beyond the first are sent to
  // it (catching up from their beds through the points before). Which fill a worker takes
  // changes only the order of the work, never what a fill computes.
  void run_carried(Progress& progress) {
    const auto last = static_cast<long>(plan_.points.size()) - 1;
    want_.assign(plan_.points.size(), plan_.first_fills);
    target_.assign(record_.beds.size(), -1);
    busy_.assign(record_.beds.size(), 0);
    for (std::size_t r = 0; r < static_cast<std::size_t>(plan_.first_fills); ++r) target_[r] = last;
    std::unique_lock<std::mutex> lock(mutex_);
    judge_ready();
    std::exception_ptr failure;
    std::condition_variable& changed = changed_;
    auto worker = [&] {
      std::unique_lock<std::mutex> held(mutex_);
      for (;;) {
        if (stop_requested()) return;
        // The fill furthest behind first: points then finish about in order.
        std::size_t pick = record_.beds.size();
        bool running = false, paused = false;
        for (std::size_t r = 0; r < record_.beds.size(); ++r) {
          running = running || busy_[r];
          if (busy_[r] || reached_[r] >= target_[r]) continue;
          // A fill paused at a look goes on once the fills it compares with have got there.
          if (look_at_[r] > 0 && look_values(r).empty()) {
            paused = true;
            continue;
          }
          if (pick == record_.beds.size() || reached_[r] < reached_[pick]) pick = r;
        }
        if (pick == record_.beds.size()) {
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

  // Judges every point whose wanted fills have all run it (mutex_ held): finished, or more
  // fills sent to it.
  void judge_ready() {
    for (std::size_t s = 0; s < plan_.points.size(); ++s) {
      if (record_.done[s]) continue;
      bool ready = true;
      for (std::size_t r = 0; r < static_cast<std::size_t>(want_[s]); ++r)
        ready = ready && record_.points[r][s].has_value();
      if (!ready) continue;
      const Ensemble e = judge_step(s, static_cast<std::size_t>(want_[s]));
      if (e.wants_fills && want_[s] < plan_.most_fills) {
        const int next = more_fills(e, want_[s], plan_.most_fills, plan_.settle.tolerance);
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
    if (plan_.steady &&
        std::any_of(record_.done.begin(), record_.done.end(), [](char d) { return d != 0; })) {
      const PlannedWork left =
          planned_remaining(plan_, *scenes_[0], record_, want_, target_, reached_);
      progress_->set_work(record_.simulated_s - simulated_start_, left.expected, left.beyond);
    }
  }

  // Runs fill r's next point (a fill's first from its settled bed) and records it.
  void run_next_point(std::size_t r, Progress& progress) {
    if (!runs_[r]) {
      ensure_bed(r, progress);
      std::lock_guard<std::mutex> lock(mutex_);  // record_.states and results_ are shared
      runs_[r] =
          std::make_unique<FrequencyRun>(scene(r), plan_, [this, r, &progress](double f, double d) {
            // d is the point's periods over max_periods (FrequencyRun::run_period())
            progress.update(r, double(reached_[r] + 1) + d, f,
                            f > 0 ? d * plan_.settle.max_periods / f : 0.0);
          });
      FrequencyRun& run = *runs_[r];
      if (const auto it = record_.states.find(r); it != record_.states.end()) {
        run.restore(it->second);
        if (r == 0) run.set_records(results_.timeseries, results_.energy, results_.particles);
      } else {
        run.restore(record_.beds[r]);
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
    record_.points[r][k] = std::move(point);
    reached_[r] = static_cast<long>(k);
    if (checkpoint_ && more) record_.states[r] = std::move(state);
    account(run, seen_[r]);
    if (r == 0) {
      results_.timeseries = run.timeseries();
      results_.energy = run.energy();
      results_.particles = run.particles();
    }
    progress_->update(r, double(k + 1), planned(k).frequency,
                      0.0);  // its time is in record_.simulated_s now
    const bool catching_up = r >= static_cast<std::size_t>(want_[k]);
    progress_->say(fill_text(*record_.points[r][k], r, plan_) +
                   (catching_up ? " (catching up)" : ""));
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
    return !independent() && plan_.first_fills >= 2 && plan_.steady &&
           plan_.settle.average_periods == 0;
  }
  // The means fill r's pending look compares (mutex_ held): its own and those of the fills
  // before it at that look, or their final ones; empty while one has not got there.
  std::vector<std::complex<double>> look_values(std::size_t r) const {
    const auto s = static_cast<std::size_t>(reached_[r] + 1), j = std::size_t(look_at_[r]);
    std::vector<std::complex<double>> values;
    for (std::size_t q = 0; q < std::max(r + 1, static_cast<std::size_t>(plan_.first_fills)); ++q) {
      const auto& posted = record_.looks[q][s];
      if (posted.size() >= j)
        values.push_back(posted[j - 1]);
      else if (record_.points[q][s])
        values.push_back(record_.points[q][s]->judged.mean);
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
      record_.looks[r][k].clear();  // a point run again after a resume posts the same means again
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
      record_.looks[r][k].push_back(mean);
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
      if (!record_.done[s]) todo.push_back(s);
    in_parallel(todo.size(), [&](std::size_t k) {
      const std::size_t s = todo[k];
      double done = 0;
      for (int want = plan_.first_fills;;) {
        for (std::size_t r = 0; r < static_cast<std::size_t>(want); ++r, done += 1) {
          if (record_.points[r][s]) continue;
          ensure_bed(r, progress);
          FrequencyRun run(scene(r), plan_,
                           [&, k](double f, double d) { progress.update(k, done + d, f); });
          run.restore(record_.beds[r]);
          Seen seen{run.system().particle_steps(), run.system().time()};
          FrequencyPoint point;
          try {
            point = run.run_point(planned(s).frequency, planned(s).amplitude);
          } catch (const SimulationError& e) {
            fail(run, r, e);
          }
          std::lock_guard<std::mutex> lock(mutex_);
          record_.points[r][s] = std::move(point);
          account(run, seen);
          if (r == 0) append_segment(run.timeseries(), s);
          progress_->say(fill_text(*record_.points[r][s], r, plan_));
        }
        const Ensemble e = judge_step(s);
        if (!e.wants_fills || want >= plan_.most_fills) break;
        const int next = more_fills(e, want, plan_.most_fills, plan_.settle.tolerance);
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
    record_.done[s] = 1;
    if (plan_.harmonics)
      progress_->say(point_text(plan_, s) + ": " + ensemble_text(judge_step(s), prescribed()));
    if (std::all_of(record_.done.begin(), record_.done.end(), [](char d) { return d != 0; }) ||
        !checkpoint_)
      return;
    Results snapshot = results_;
    add_rows(snapshot);  // the finished points are readable (and plottable) in the .partial
    put_checkpoint(
        record_,
        record_.wall_before_s + std::chrono::duration<double>(Clock::now() - started_).count(),
        snapshot.checkpoint);
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

  void provenance(Results& r) const {
    RunFacts f;
    f.scene = scenes_[0].get();
    f.plan = &plan_;
    f.identity = identity_;
    f.backend = backend_;
    f.variant = variant_;
    f.bed = record_.reports[0];
    f.bed_from_file = record_.bed_from_file;
    f.fills_min = plan_.first_fills;
    f.fills_max = plan_.most_fills;
    for (std::size_t k = 0; k < record_.points.size(); ++k)
      for (const auto& p : record_.points[k])
        f.fills_used = p ? std::max(f.fills_used, k + 1) : f.fills_used;
    f.jobs = jobs_;
    f.threads = threads_;
    f.wall_s = wall_;
    f.simulated_s = record_.simulated_s;
    f.particle_steps = record_.particle_steps;
    f.solver_start = solver_start_;
    write_provenance(r, deck_, f);
  }

  const DeckRecord deck_;
  const RunPlan plan_;                // every fill's FrequencyRun reads it
  RunRecord record_;                  // what the fills have done: the checkpoint's contents
  std::string identity_;              // fill 0's scene's (src/identity.hpp), taken once
  std::optional<Results> kept_beds_;  // read from bed.file before the run (read_bed_file())
  SceneMaker make_scene_;
  std::vector<std::unique_ptr<Scene>> scenes_;  // one per fill, built when first needed
  std::mutex scene_mutex_;
  int jobs_;
  bool quiet_;
  std::string dump_path_;
  std::unique_ptr<std::once_flag[]> bed_once_;
  std::vector<std::unique_ptr<FrequencyRun>> runs_;  // carried: each fill's run
  std::vector<long> reached_;        // carried: the last point each fill ran (-1: none)
  std::vector<long> target_;         // carried: the last point each fill is to run
  std::vector<int> want_;            // carried: the fills each point wants
  std::vector<char> busy_;           // carried: a worker is running the fill
  std::vector<int> look_at_;         // carried: the look each fill is paused at (0: none)
  std::condition_variable changed_;  // carried: a fill finished a point, paused or posted a look
  std::vector<Seen> seen_;
  std::map<std::size_t, TimeSeries> segments_;
  Results results_;
  std::function<void(const Results&)> checkpoint_;
  Progress* progress_ = nullptr;
  SolverTotals solver_start_ = nonsmooth_totals();  // the non-smooth solves before this run
  std::mutex mutex_;
  int stop_after_ = 0;
  std::atomic<bool> stopped_{false};
  std::optional<Results> failed_;
  std::size_t finished_ = 0;  // points finished in this process
  double wall_ = 0;
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
