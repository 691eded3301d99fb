#include "src/run.hpp"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <sstream>

#include "pdsim_version.hpp"
#include "src/harmonics.hpp"
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
}

using Clock = std::chrono::steady_clock;

// Progress on stderr: a rewritten line on a terminal, a line every few seconds otherwise.
class Progress {
 public:
  explicit Progress(bool quiet) : quiet_(quiet), tty_(isatty(fileno(stderr)) != 0) {}
  void update(double sim_time, double frequency, double fraction_done) {
    if (quiet_) return;
    const auto now = Clock::now();
    if (now - last_ < (tty_ ? std::chrono::milliseconds(250) : std::chrono::seconds(5))) return;
    last_ = now;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const double eta = fraction_done > 1e-3 ? elapsed * (1 - fraction_done) / fraction_done : 0;
    std::fprintf(stderr, "%st = %.4f s  f = %.3f Hz  %5.1f%%  elapsed %.0f s  ETA %.0f s%s",
                 tty_ ? "\r" : "", sim_time, frequency, 100 * fraction_done, elapsed, eta,
                 tty_ ? "   " : "\n");
    std::fflush(stderr);
  }
  void finish() {
    if (!quiet_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  bool quiet_, tty_;
  Clock::time_point start_ = Clock::now(), last_{};
};

class Runner {
 public:
  Runner(const Deck& deck, const Scene& scene, bool quiet)
      : deck_(deck), scene_(scene), system_(deck, scene), progress_(quiet) {
    const ExcitationSpec& x = deck.excitation;
    frequencies_ = x.frequencies;
    if (x.kind == ExcitationKind::sine) frequencies_ = {x.frequency};
    if (x.kind == ExcitationKind::prescribed && frequencies_.empty())
      frequencies_ = {x.motion.frequency};
    const double f_top = scene.highest_frequency > 0 ? scene.highest_frequency : first_mode();
    sample_every_ = deck.output.every > 0 ? deck.output.every : 1.0 / (32 * f_top);
    if (deck.output.energy) results_.energy.emplace();
  }

  // Continues from a checkpoint written after frequency `next_ - 1`.
  void resume_from(const Results& partial) {
    results_.timeseries = partial.timeseries;
    results_.frf = partial.frf;
    results_.prescribed = partial.prescribed;
    results_.energy = partial.energy;
    system_.restore(partial.checkpoint);
    next_ = static_cast<std::size_t>(partial.checkpoint.at("next_frequency").at(0));
    next_sample_ = partial.checkpoint.at("next_sample").at(0);
    dissipated_n_ = partial.checkpoint.at("tallies").at(0);
    dissipated_t_ = partial.checkpoint.at("tallies").at(1);
    work_in_ = partial.checkpoint.at("tallies").at(2);
  }

  // Runs what is left; `checkpoint` is called after every finished frequency. With
  // stop_after > 0, returns after that many frequencies (stopped() tells).
  Results run(const std::function<void(const Results&)>& checkpoint, int stop_after = 0) {
    const auto start = Clock::now();
    const ExcitationSpec& x = deck_.excitation;
    if (x.kind == ExcitationKind::free_decay) {
      const double f1 = first_mode();
      configure(f1, 0.0);
      system_.set_initial_displacement(x.initial_displacement);
      while (system_.time() < x.duration - 1e-12) {
        step();
        progress_.update(system_.time(), f1, system_.time() / x.duration);
      }
    }
    for (; next_ < frequencies_.size(); ++next_) {
      run_frequency(frequencies_[next_]);
      if (checkpoint && next_ + 1 < frequencies_.size()) {
        Results snapshot = results_;
        snapshot.checkpoint = system_.save();
        snapshot.checkpoint["next_frequency"] = {static_cast<double>(next_ + 1)};
        snapshot.checkpoint["next_sample"] = {next_sample_};
        snapshot.checkpoint["tallies"] = {dissipated_n_, dissipated_t_, work_in_};
        checkpoint(snapshot);
        if (--stop_after == 0) {
          stopped_ = true;
          ++next_;
          break;
        }
      }
    }
    progress_.finish();
    wall_time_ += std::chrono::duration<double>(Clock::now() - start).count();
    provenance();
    return results_;
  }

  double wall_time() const { return wall_time_; }
  bool stopped() const { return stopped_; }
  void dump(const std::string& path) const { system_.dump(path); }
  std::size_t finished() const { return next_; }

 private:
  double first_mode() const {
    if (!system_.has_structure()) return 1.0;
    return natural_frequencies(system_.structure()).front();
  }

  // Fixes the step for frequency f: an integer number of steps (a multiple of the coupling
  // interval) per period, no longer than the scene's dt.
  int configure(double frequency, double amplitude) {
    const double period = 1.0 / frequency;
    const int every = system_.steps_per_advance();
    int steps = static_cast<int>(std::ceil(period / scene_.dt / every - 1e-9)) * every;
    steps = std::max(steps, 32 * every);
    Drive drive{deck_.excitation.input, amplitude, 2 * kPi * frequency};
    system_.configure(period / steps, drive);
    dt_ = period / steps;
    return steps / every;
  }

  void step() {
    if (g_interrupted) throw SimulationError("interrupted");
    system_.advance();
    const StepRecord& r = system_.last();
    const double h = dt_ * system_.steps_per_advance();
    dissipated_n_ += r.dissipated_normal;
    dissipated_t_ += r.dissipated_tangential;
    work_in_ += r.work_external + (system_.has_structure() ? 0.0 : r.power_in * h);
    if (r.time + 1e-12 >= next_sample_) {
      next_sample_ += sample_every_;
      TimeSeries& ts = results_.timeseries;
      ts.time.push_back(r.time);
      ts.displacement.push_back(r.displacement);
      ts.velocity.push_back(r.velocity);
      ts.damper_force.push_back(r.damper_force);
      if (results_.energy) {
        EnergySeries& e = *results_.energy;
        e.time.push_back(r.time);
        e.kinetic.push_back(r.particle_kinetic + system_.structure_kinetic());
        e.elastic.push_back(system_.structure_elastic());
        e.dissipated_normal.push_back(dissipated_n_);
        e.dissipated_tangential.push_back(dissipated_t_);
        e.work_in.push_back(work_in_);
      }
    }
    if (!std::isfinite(r.displacement))
      throw SimulationError("the structure response became non-finite at t = " + number(r.time) +
                            " s");
  }

  void run_frequency(double frequency) {
    const ExcitationSpec& x = deck_.excitation;
    const bool prescribed = x.kind == ExcitationKind::prescribed;
    const int samples = configure(frequency, prescribed ? x.motion.amplitude : x.amplitude);
    PeriodTracker tracker(2 * kPi * frequency, samples);
    const SettleSpec& settle = x.settle;
    const bool fixed = x.kind == ExcitationKind::sine || (prescribed && x.duration > 0);
    // A fixed run (sine, or prescribed with a duration) takes whole periods of its duration.
    const int max_periods = fixed
                                ? std::max(1, static_cast<int>(std::lround(x.duration * frequency)))
                                : settle.max_periods;
    bool converged = false;
    while (tracker.periods() < max_periods) {
      for (int s = 0; s < samples; ++s) {
        step();
        tracker.add(system_.last(), dt_ * system_.steps_per_advance());
      }
      converged = tracker.converged(settle.tolerance, settle.min_periods, prescribed);
      const double within = static_cast<double>(tracker.periods()) / max_periods;
      progress_.update(
          system_.time(), frequency,
          (static_cast<double>(next_) + within) / static_cast<double>(frequencies_.size()));
      if (!fixed && converged) break;
    }
    const PeriodSummary m = tracker.average(settle.average_periods);
    if (prescribed) {
      PrescribedTable& p = results_.prescribed;
      p.frequency.push_back(frequency);
      p.dissipated_power.push_back(m.energy_in * frequency);
      p.force_amplitude.push_back(std::abs(m.force));
      p.force_phase.push_back(std::arg(m.force));
      return;
    }
    FrfTable& f = results_.frf;
    f.frequency.push_back(frequency);
    f.amplitude.push_back(std::abs(m.displacement));
    f.phase.push_back(std::arg(m.displacement));
    f.rms.push_back(std::sqrt(m.mean_square));
    f.peak.push_back(m.peak);
    f.periods.push_back(tracker.periods());
    f.converged.push_back(converged ? 1 : 0);
    f.dissipated_energy.push_back(m.energy_in);
    f.dissipated_normal.push_back(m.dissipated_normal);
    f.dissipated_tangential.push_back(m.dissipated_tangential);
  }

  void provenance() {
    auto& t = results_.meta_text;
    auto& n = results_.meta_numbers;
    t["deck"] = deck_.text;
    t["deck_path"] = deck_.path;
    if (deck_.point > 0)
      t["sweep_point"] = std::to_string(deck_.point) + ": " + deck_.sweep.describe(deck_.point);
    t["title"] = deck_.title;
    t["version"] = std::string(PDSIM_VERSION) + " (" + PDSIM_GIT + ")";
    const auto& engines = system_.engines();
    t["backend"] = engines.empty() ? std::string("none (no particles)") : engines[0]->backend();
    t["kernel_variant"] = engines.empty() ? std::string("none") : engines[0]->variant();
    const char* schemes[] = {"loose", "interleaved", "tight"};
    t["coupling"] = schemes[static_cast<int>(deck_.coupling.scheme)];
    t["dt_basis"] = scene_.dt_basis;
    n["threads"] = engines.empty() ? 1 : engines[0]->threads();
    n["dt"] = scene_.dt;
    n["dt_limit"] = scene_.dt_limit;
    n["wall_time_s"] = wall_time_;
    n["particle_steps"] = static_cast<double>(system_.particle_steps());
    n["particles"] = system_.particle_count();
    n["simulated_time_s"] = system_.time();
  }

  const Deck& deck_;
  const Scene& scene_;
  CoupledSystem system_;
  Progress progress_;
  Results results_;
  std::vector<double> frequencies_;
  std::size_t next_ = 0;
  bool stopped_ = false;
  double dt_ = 0, sample_every_ = 0, next_sample_ = 0, wall_time_ = 0;
  double dissipated_n_ = 0, dissipated_t_ = 0, work_in_ = 0;
};

std::string summary_line(const Results& r, const std::string& path) {
  std::ostringstream s;
  s.precision(4);
  if (!r.frf.frequency.empty()) {
    const auto& a = r.frf.amplitude;
    const auto peak = std::max_element(a.begin(), a.end()) - a.begin();
    int converged = 0;
    for (int c : r.frf.converged) converged += c;
    s << "FRF: " << a.size() << " frequencies, peak amplitude " << 1e3 * a[std::size_t(peak)]
      << " mm at " << r.frf.frequency[std::size_t(peak)] << " Hz, " << converged << "/" << a.size()
      << " converged";
  } else if (!r.prescribed.frequency.empty()) {
    s << "prescribed motion: " << r.prescribed.frequency.size() << " frequencies, power "
      << r.prescribed.dissipated_power.back() << " W, force amplitude "
      << r.prescribed.force_amplitude.back() << " N at " << r.prescribed.frequency.back() << " Hz";
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

Results simulate(const Deck& deck, const Scene& scene, bool quiet) {
  Runner runner(deck, scene, quiet);
  return runner.run({});
}

RunReport run_deck(const Deck& deck, const RunOptions& options) {
  const std::string path = output_path(deck, options);
  const std::string partial = path + ".partial";
  namespace fs = std::filesystem;
  if (deck.sweep.points() > 0 && deck.point == 0)
    throw InputError(deck.path + ": the deck has a [sweep] table of " +
                     std::to_string(deck.sweep.points()) +
                     " points; run them all with `pdsim sweep`, or one with `pdsim run --point K`");
  if (fs::exists(path) && !options.force)
    throw InputError(path + ": output file exists; use --force to overwrite it");
  const Scene scene = build_scene(deck, options.threads, options.backend);
  if (const fs::path folder = fs::path(path).parent_path(); deck.point > 0 && !folder.empty())
    fs::create_directories(folder);
  Runner runner(deck, scene, options.quiet);
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
    runner.resume_from(saved);
  }
  g_interrupted = 0;
  auto previous = std::signal(SIGINT, on_interrupt);
  Results results;
  try {
    results = runner.run(
        [&](const Results& snapshot) {
          Results r = snapshot;
          r.meta_text["deck"] = deck.text;
          write_results(path, r, false);
        },
        options.stop_after);
  } catch (const SimulationError& e) {
    std::signal(SIGINT, previous);
    if (g_interrupted)
      throw SimulationError(std::string("interrupted; finished frequencies are in ") + partial +
                            ", continue with --resume");
    const std::string dump = path + ".blowup.csv";
    runner.dump(dump);
    throw SimulationError(std::string(e.what()) + "\nparticle states written to " + dump);
  }
  std::signal(SIGINT, previous);
  if (runner.stopped())
    return {partial, "stopped after " + std::to_string(runner.finished()) +
                         " frequencies as asked; continue with --resume"};
  write_results(path, results, true);
  return {path, summary_line(results, path)};
}

std::string check_report(const Deck& deck, const Scene& scene) {
  std::ostringstream s;
  s.precision(5);
  s << "deck: " << deck.path << (deck.title.empty() ? "" : " (" + deck.title + ")") << "\n";
  double structure_mass = 0;
  if (deck.structure.kind != StructureKind::none) {
    const LinearStructure st = build_structure(deck);
    const auto f = natural_frequencies(st);
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
    steps_per_second = 1.0 / scene.dt;
  }
  s << "backend: " << backend_name(scene.backend) << " (" << scene.backend_reason << ")\n";
  if (scene.highest_frequency > 0) {
    s << "steps per period: "
      << static_cast<long>(std::ceil(1.0 / (scene.highest_frequency * scene.dt))) << " at "
      << scene.highest_frequency << " Hz\n";
  }
  // Estimated cost: simulated time x steps/s x particles, at an assumed 1e7 particle-steps/s.
  const ExcitationSpec& x = deck.excitation;
  double simulated = 0;
  if (x.kind == ExcitationKind::stepped_sine)
    for (double f : x.frequencies) simulated += x.settle.max_periods / f;
  else if (x.kind == ExcitationKind::prescribed && x.duration <= 0)
    for (double f :
         (x.frequencies.empty() ? std::vector<double>{x.motion.frequency} : x.frequencies))
      simulated += x.settle.max_periods / f;
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
