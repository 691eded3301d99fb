#include "src/bench.hpp"

#include <CLI/CLI.hpp>
#include <toml++/toml.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <numeric>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include "io/deck.hpp"
#include "kernels/contact_count.hpp"
#include "pdsim_saeki_deck.hpp"
#include "src/coupled_system.hpp"
#include "src/frequency_run.hpp"
#include "src/scene.hpp"

namespace pdsim {
namespace {

// The benchmark scene (issue 5): steel spheres d = 5 mm, Hertz + Mindlin history, gravity,
// dt = 1e-6 s, lattice start, box shaken 0.004 sin(2 pi 20 t) along x.
DamperSpec shaken_box(int particles) {
  DamperSpec d;
  d.container.shape = WallShape::box;
  if (particles <= 250)
    d.container.size = {0.04, 0.04, 0.04};
  else if (particles <= 8000)
    d.container.size = {0.11, 0.11, 0.2};
  else
    d.container.size = {0.26, 0.26, 0.4 * particles / 100000.0 + 0.02};
  d.particles.count = particles;
  d.particles.diameter = 0.005;
  d.particles.density = 7800;
  d.particles.fill = Fill::lattice;
  return d;
}

struct Effect {
  const char* name;
  NormalModel normal;
  TangentialModel tangential;
  bool gravity, rolling, polydisperse;
};

// How a bench scene's container moves along x: amplitude (m) and frequency (Hz).
struct Shake {
  double amplitude, frequency;
};
constexpr Shake kBoxShake{0.004, 20.0};   // the shaken box, fluidised
constexpr Shake kPileShake{0.001, 15.0};  // the Saeki-size pile, which barely moves

// Wall seconds since `start`.
double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The shaken container at step n.
ContainerKinematics shaken(Shake s, long n, double dt) {
  const double omega = 2 * kPi * s.frequency, t = static_cast<double>(n) * dt;
  return translating({s.amplitude * std::sin(omega * t), 0, 0},
                     {s.amplitude * omega * std::cos(omega * t), 0, 0});
}

// Steps of the shaken container from step `first` on (its phase follows the step count).
void shake(DemEngine& engine, double dt, long first, long steps, Shake s = kBoxShake) {
  for (long n = first; n < first + steps; ++n) {
    const StepTotals& totals = engine.compute(shaken(s, n, dt), dt);
    if (totals.flags) throw SimulationError("bench scene blew up");
    engine.accept();
  }
}

// A fingerprint of the final state, printed with every digit: two builds that compute the same
// trajectories print the same value (an engine change meant to keep results bitwise is checked
// against the commit before it this way).
double state_sum(const DemEngine& engine) {
  double sum = 0;
  for (const ParticleState& p : engine.particles())
    sum += p.position.x + p.position.y + p.position.z + p.velocity.x + p.velocity.y + p.velocity.z +
           1e-3 * (p.spin.x + p.spin.y + p.spin.z);
  return sum;
}

// Wall time of a whole run: engine set-up and `steps` steps from step `first`. `bytes` and `sum`,
// when given, receive the engine's memory per particle at the end (its lists sized by the run)
// and state_sum().
double time_engine(const EngineConfig& config, long steps, long long* particle_steps,
                   long first = 0, std::size_t* bytes = nullptr, double* sum = nullptr) {
  const auto start = std::chrono::steady_clock::now();
  auto engine = make_engine(config);
  shake(*engine, config.dt, first, steps);
  *particle_steps = static_cast<long long>(steps) * engine->count();
  const double wall = seconds_since(start);
  if (bytes) *bytes = engine->bytes_per_particle();
  if (sum) *sum = state_sum(*engine);
  return wall;
}

// Steel spheres d = 5 mm (7800 kg/m^3) filled into the box of `d` as `d` says, Hertz + Mindlin
// history with Young's modulus `young` and restitution `restitution`, mu = 0.3, gravity.
EngineConfig steel_spheres(const DamperSpec& d, double young, double restitution, double dt,
                           int threads, Backend backend) {
  EngineConfig c;
  c.backend = backend;
  c.threads = threads;
  c.geometry.half_size = 0.5 * d.container.size;
  c.radius.assign(static_cast<std::size_t>(d.particles.count), 0.0025);
  c.density = 7800;
  c.gravity = Vec3{0, 0, -9.81};
  c.dt = dt;
  c.contact = hertz_contact(young, 0.3, restitution, 0.3);
  for (const Vec3& p : fill_particles(WallShape::box, c.geometry, d.particles, c.radius,
                                      SourcePos{"bench", 0, 0}, "bench"))
    c.particles.push_back({p, {}, {}});
  return c;
}

EngineConfig bench_config(int particles, int threads, Backend backend, Fill fill = Fill::lattice) {
  DamperSpec d = shaken_box(particles);
  d.particles.fill = fill;
  EngineConfig c = steel_spheres(d, 2e11, 0.5, 1e-6, threads, backend);
  c.contact.linear_stiffness = 1e6;
  c.contact.rolling_friction = 0.01;
  return c;
}

// The damper of examples/saeki_250.toml as a dense pile: 250 steel spheres d = 5 mm, randomly
// filled into a 50 mm cube, Hertz (E softened to 2e9 Pa, as the example) + Mindlin history,
// e = 0.6, mu = 0.3, gravity, dt = 4e-6 s (0.15 Rayleigh times; validation/liggghts/ uses the
// same); shaken 1 mm at 15 Hz, it stays a pile.
EngineConfig pile_config(Backend backend) {
  DamperSpec d = shaken_box(250);
  d.container.size = {0.05, 0.05, 0.05};
  d.particles.fill = Fill::random;
  return steel_spheres(d, 2e9, 0.6, 4e-6, 1, backend);
}

long period_steps(double periods, Shake s, double dt) {
  return std::max(1L, std::lround(periods / (s.frequency * dt)));
}

// A scene after its warm-up (the fall from the fill, untimed): the engine's state and the step
// it ends at.
struct Warmed {
  StateArrays state;
  long step = 0;
};
Warmed warm_up(const EngineConfig& config, Shake s, double seconds) {
  Warmed w;
  w.step = std::lround(seconds / config.dt);
  auto engine = make_engine(config);
  shake(*engine, config.dt, 0, w.step, s);
  w.state = engine->save();
  return w;
}

// `steps` steps of the scene from its warmed state, set-up excluded: wall s; `engine` keeps the
// engine for its figures.
double time_warmed(const EngineConfig& config, const Warmed& w, long steps, Shake s,
                   std::unique_ptr<DemEngine>& engine) {
  engine = make_engine(config);
  engine->restore(w.state);
  const auto start = std::chrono::steady_clock::now();
  shake(*engine, config.dt, w.step, steps, s);
  return seconds_since(start);
}

// Contacts per particle of an engine's state (partners and walls), with its container at
// `container`: the coordination of the flow.
double contacts_per_particle(const DemEngine& engine, const EngineConfig& config,
                             const ContainerKinematics& container) {
  std::vector<Vec3> centre;
  for (const ParticleState& p : engine.particles()) centre.push_back(p.position);
  const std::vector<std::int32_t> contacts =
      contact_counts(centre, config.radius, config.shape, config.geometry, container);
  return std::accumulate(contacts.begin(), contacts.end(), 0.0) /
         static_cast<double>(centre.size());
}

// The median and range of repeated timings.
struct Spread {
  double median, min, max;
};
Spread spread(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return {n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]), v.front(), v.back()};
}
std::string range_text(const Spread& s) {
  char text[64];
  std::snprintf(text, sizeof text, "[%.3g, %.3g]", s.min, s.max);
  return text;
}

// One scene the user runs: warmed up once, then timed over whole periods from the same state at
// each thread count, o.repeat times (the same trajectory each time).
void bench_flow(const char* title, EngineConfig config, Shake s, const BenchOptions& o) {
  const long steps = period_steps(o.periods, s, config.dt);
  std::printf(
      "\n# %s; shaken %g mm at %g Hz along x, dt = %g s: %g s of warm-up from a "
      "random fill (untimed), then %g periods (%ld steps) timed, median and range of %d runs\n",
      title, 1e3 * s.amplitude, s.frequency, config.dt, o.warmup, o.periods, steps, o.repeat);
  std::printf("%-10s %-8s %-9s %-10s %-14s %-22s %-16s %-9s %-34s %s\n", "particles", "threads",
              "steps", "wall_s", "psteps_per_s", "range", "bytes/particle", "contacts", "variant",
              "state_sum");
  config.threads = *std::max_element(o.threads.begin(), o.threads.end());
  const Warmed warmed = warm_up(config, s, o.warmup);
  for (int t : o.threads) {
    config.threads = t;
    std::unique_ptr<DemEngine> engine;
    std::vector<double> walls, rates;
    for (int r = 0; r < o.repeat; ++r) {
      walls.push_back(time_warmed(config, warmed, steps, s, engine));
      rates.push_back(static_cast<double>(steps) * engine->count() / walls.back());
    }
    const Spread rate = spread(rates);
    const double per_particle =
        contacts_per_particle(*engine, config, shaken(s, warmed.step + steps, config.dt));
    std::printf("%-10d %-8d %-9ld %-10.3f %-14.4g %-22s %-16zu %-9.2f %-34s %.17g\n",
                engine->count(), t, steps, spread(walls).median, rate.median,
                range_text(rate).c_str(), engine->bytes_per_particle(), per_particle,
                engine->variant().c_str(), state_sum(*engine));
    std::fflush(stdout);
  }
}

// The same scene with rigid contacts (kernels/nonsmooth.hpp), its step as a scene takes it:
// `safety` r over twice the container's peak speed plus a fall across the container. The walls
// keep their velocity at the step's start (a prescribed scene's move at the chord's), and the
// tolerance is the rest speed (a scene's too where a tenth of its containers' speed is faster).
EngineConfig rigid_config(EngineConfig c, Shake s, double safety) {
  const double r = c.radius.front(), g = 9.81;
  const double speed =
      2 * 2 * kPi * s.frequency * s.amplitude + std::sqrt(2 * g * 2 * c.geometry.half_size.z);
  c.dt = safety * r / speed;
  c.nonsmooth = nonsmooth_params(0.6, c.contact.friction, speed, c.dt, g);
  return c;
}

// Rigid contacts against the penalty engine at the example's stiffness (2e9 Pa) and steel's
// (2e11 Pa), each at 0.15 Rayleigh times, on one thread: simulated periods per wall second,
// alternated (each round runs every model once) and the median taken.
void bench_rigid(const BenchOptions& o) {
  struct Scene {
    std::string title;
    DamperSpec damper;
    Shake shake;
  };
  std::vector<Scene> scenes;
  if (o.pile) {
    DamperSpec pile = shaken_box(250);
    pile.container.size = {0.05, 0.05, 0.05};
    pile.particles.fill = Fill::random;
    scenes.push_back({"the Saeki pile, 250 spheres in a 50 mm cube", pile, kPileShake});
  }
  if (o.box)
    for (int n : o.particles) {
      DamperSpec box = shaken_box(n);
      box.particles.fill = Fill::random;
      scenes.push_back({"shaken box, " + std::to_string(n) + " spheres", box, kBoxShake});
    }
  for (const Scene& scene : scenes) {
    std::printf(
        "\n# rigid against penalty contacts: %s, d = 5 mm steel, e = 0.6, mu = 0.3, gravity, "
        "shaken %g mm at %g Hz; %g s of warm-up (untimed), then %g periods timed, median of %d "
        "alternated rounds, one thread\n",
        scene.title.c_str(), 1e3 * scene.shake.amplitude, scene.shake.frequency, o.warmup,
        o.periods, o.repeat);
    std::printf("%-28s %-11s %-10s %-10s %-16s %-12s %-14s %s\n", "contacts", "dt_s", "steps",
                "wall_s", "periods_per_s", "iterations", "in_problem", "variant");
    std::vector<std::pair<std::string, EngineConfig>> models;
    for (double young : {2e9, 2e11}) {
      EngineConfig c = steel_spheres(scene.damper, young, 0.6, 1, 1, Backend::cpu);
      c.dt = 0.15 * rayleigh_time(0.0025, 7800, young, 0.3);
      models.push_back({young < 1e10 ? "penalty E = 2e9 Pa" : "penalty E = 2e11 Pa (steel)", c});
    }
    for (double safety : {0.2, 0.1})  // the default dt_safety, and half of it
      models.push_back({"rigid, dt_safety " + std::to_string(safety).substr(0, 3),
                        rigid_config(models.front().second, scene.shake, safety)});
    std::vector<Warmed> warmed;
    for (const auto& m : models) warmed.push_back(warm_up(m.second, scene.shake, o.warmup));
    std::vector<std::vector<double>> walls(models.size());
    std::vector<double> iterations(models.size(), 0), contacts(models.size(), 0);
    for (int r = 0; r < o.repeat; ++r)
      for (std::size_t k = 0; k < models.size(); ++k) {
        const EngineConfig& c = models[k].second;
        std::unique_ptr<DemEngine> engine;
        const SolverTotals before = nonsmooth_totals();
        walls[k].push_back(time_warmed(c, warmed[k], period_steps(o.periods, scene.shake, c.dt),
                                       scene.shake, engine));
        const SolverTotals after = nonsmooth_totals();
        if (after.steps > before.steps) {
          const double steps = static_cast<double>(after.steps - before.steps);
          iterations[k] = static_cast<double>(after.iterations - before.iterations) / steps;
          contacts[k] = static_cast<double>(after.contacts - before.contacts) / steps;
        }
      }
    for (std::size_t k = 0; k < models.size(); ++k) {
      const EngineConfig& c = models[k].second;
      const double wall = spread(walls[k]).median;
      char solver[2][32] = {"-", "-"};
      if (c.nonsmooth) {
        std::snprintf(solver[0], sizeof solver[0], "%.1f", iterations[k]);
        std::snprintf(solver[1], sizeof solver[1], "%.0f", contacts[k]);
      }
      std::printf("%-28s %-11.4g %-10ld %-10.3f %-16.4g %-12s %-14s %s\n", models[k].first.c_str(),
                  c.dt, period_steps(o.periods, scene.shake, c.dt), wall, o.periods / wall,
                  solver[0], solver[1], variant_name(c).c_str());
      std::fflush(stdout);
    }
  }
}

}  // namespace

void add_bench_options(CLI::App& app, BenchOptions& o) {
  app.add_option("--particles", o.particles, "particle counts (e.g. 196,8000,100000)")
      ->delimiter(',');
  app.add_option("--threads", o.threads, "thread counts to compare (e.g. 1,2)")->delimiter(',');
  app.add_option("--steps", o.steps,
                 "instead of whole periods: this many steps of the box from its lattice, set-up "
                 "included (the first steps are nearly free fall; validation/bench_vs_liggghts.sh)")
      ->check(CLI::Range(1L, 1000000000L));
  app.add_option("--warmup", o.warmup,
                 "seconds of shaking before the timing: the fall from the fill (default 0.2)")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--periods", o.periods, "whole periods timed (default 1)")
      ->check(CLI::Range(0.01, 1000.0));
  app.add_option("--repeat", o.repeat,
                 "time each flow this many times from the same state and print the median and "
                 "the range (default 3; this machine's runs differ by up to a third)")
      ->check(CLI::Range(1, 1000));
  app.add_flag("--box,!--no-box", o.box,
               "the shaken box at each --particles count (default on; --no-box: the pile only)");
  app.add_flag("--saeki,!--no-saeki", o.saeki,
               "also the Saeki example coupled to its structure at 13 Hz, against the same bed's "
               "DEM alone (default on; not with --steps)");
  app.add_flag("--pile,!--no-pile", o.pile,
               "also the dense Saeki-size pile (default on; not with --steps)");
  app.add_option("--jobs", o.jobs,
                 "also run this many copies of each scene at once, one thread each, as the points "
                 "of `pdsim sweep` run")
      ->check(CLI::Range(1, 4096));
  app.add_flag("--effects", o.effects, "time each optional effect against the full model");
  app.add_flag("--rigid", o.rigid,
               "rigid (non-smooth) contacts against the penalty engine at 2e9 and 2e11 Pa: the "
               "pile and the shaken box at each --particles count (--no-pile, --no-box)");
  app.add_flag("--coupling", o.coupling,
               "time one coupling exchange (sdof, 20-element beam) per scheme and integrator");
  app.add_option("--backend", o.backend, "cpu or cuda")->check(CLI::IsMember({"cpu", "cuda"}));
}

namespace {

// A structure with one damper holding a single particle that touches no wall: advance() then
// costs the structure step plus the exchange (kinematics out, force in), and a negligible DEM.
// Read as a user's deck is, so that it is checked as one.
Deck exchange_deck(bool beam, const char* scheme, const char* integrator) {
  const std::string structure =
      beam ? "kind = \"beam\"\nlength = 0.5\nelements = 20\nyoung = 7.0e10\ndensity = 2700.0\n"
             "section = { area = 1.5e-4, inertia = 3.125e-10 }\n"  // 30 x 5 mm
             "damping_ratio = 0.005\ndirection = [0.0, 0.0, 1.0]\n"
           : "kind = \"sdof\"\nmass = 2.37\nstiffness = 21500.0\ndamping = 0.1\n"
             "direction = [1.0, 0.0, 0.0]\n";
  return parse_deck(
      "[structure]\n" + structure + "integrator = \"" + integrator +
          "\"\n[[damper]]\ncontainer = { shape = \"box\", size = [0.05, 0.05, 0.05] }\n"
          "particles = { count = 1, diameter = 0.005, density = 7800.0, fill = \"lattice\" }\n" +
          (beam ? "attach = { node = 20 }\n" : "") +
          "[contact]\nyoung = 2.0e9\n[coupling]\nscheme = \"" + scheme +
          "\"\n[excitation]\nkind = \"sine\"\namplitude = 1.0\nfrequency = 15.0\n"
          "duration = 1.0\n",
      "pdsim bench (coupling exchange)");
}

void bench_coupling() {
  std::printf(
      "\n# coupling exchange: one advance() with a damper whose particle touches nothing\n");
  std::printf("%-6s %-12s %-12s %-12s\n", "model", "integrator", "scheme", "us_per_step");
  const char* schemes[] = {"loose", "interleaved", "tight"};
  for (bool beam : {false, true})
    for (IntegratorKind integrator : {IntegratorKind::exact, IntegratorKind::cvode})
      for (int k = 0; k < 3; ++k) {
        const Deck d = exchange_deck(beam, schemes[k],
                                     integrator == IntegratorKind::exact ? "exact" : "cvode");
        std::optional<Scene> built;
        try {
          built.emplace(build_scene(d, 1));
        } catch (const InputError&) {
          // The full 20-element beam's stiff modes are not resolved at this step: interleaved
          // coupling refuses it, as it would the user's deck.
          std::printf("%-6s %-12s %-12s refused (unresolved modes; see coupling.scheme)\n",
                      beam ? "beam20" : "sdof",
                      integrator == IntegratorKind::exact ? "exact" : "cvode", schemes[k]);
          continue;
        }
        const Scene& scene = *built;
        CoupledSystem system(scene);
        system.configure(1e-5, Drive{ExcitationInput::force, 1.0, 2 * kPi * 15});
        const int steps = integrator == IntegratorKind::exact ? 20000 : 2000;
        const auto start = std::chrono::steady_clock::now();
        for (int n = 0; n < steps; ++n) system.advance();
        const double us = 1e6 * seconds_since(start) / steps;
        std::printf("%-6s %-12s %-12s %-12.3f\n", beam ? "beam20" : "sdof",
                    integrator == IntegratorKind::exact ? "exact" : "cvode", schemes[k], us);
      }
  // The DEM step it is compared with: the Saeki scene (250 spheres, 50 mm box), one thread.
  DamperSpec saeki = shaken_box(250);
  saeki.container.size = {0.05, 0.05, 0.05};
  const EngineConfig c = steel_spheres(saeki, 2e11, 0.5, 1e-6, 1, Backend::cpu);
  long long ps = 0;
  const long steps = 20000;
  const double wall = time_engine(c, steps, &ps);
  std::printf("DEM step, 250 spheres (Saeki size, lattice start), 1 thread: %.3f us\n",
              1e6 * wall / static_cast<double>(steps));
}

// The coupled run's own cost: the Saeki damper on its structure, driven at 13 Hz (below
// resonance: the bed stays a dense pile), then the same bed's DEM alone from the same state,
// its container moved as the coupled run moved it. One thread each.
void bench_saeki(const BenchOptions& o, Backend backend) {
  // The example as the user runs it, driven at one frequency below resonance: its deck with a
  // sine of the same drive in [excitation], read and checked as a user's deck is.
  toml::table root = toml::parse(kSaekiDeck);
  const toml::table& sweep = *root["excitation"].as_table();
  toml::table sine{{"kind", "sine"}, {"frequency", 13.0}, {"duration", 1.0}};
  for (const char* key : {"input", "amplitude"})
    if (const toml::node* value = sweep.get(key)) sine.insert(key, *value);
  root.insert_or_assign("excitation", std::move(sine));
  std::ostringstream text;
  text << root;
  const Deck deck = parse_deck(text.str(), "examples/saeki_250.toml at 13 Hz (compiled in)");
  const Scene scene = build_scene(deck, 1, backend);
  const double dt = scene.dt, frequency = deck.excitation.frequencies.front();
  const RunPlan plan = plan_of(deck, scene);
  FrequencyRun run(scene, plan);  // the bed settles in the resting container first, as a run's does
  const BedReport settled = run.settle_bed();
  CoupledSystem& system = run.system();
  system.configure(dt,
                   Drive{ExcitationInput::force, deck.excitation.amplitude, 2 * kPi * frequency});
  const int every = system.steps_per_advance();
  const long warm = std::lround(o.warmup / dt);
  const long steps = std::max(1L, std::lround(o.periods / (frequency * dt)) / every) * every;
  std::printf(
      "\n# the Saeki damper (examples/saeki_250.toml) on its SDOF, %g N at %g Hz, dt = %.4g s, one "
      "thread: bed settled (%.2f s), %g s of warm-up, then %g periods (%ld steps) timed, coupled "
      "and then the DEM alone from the same state\n",
      deck.excitation.amplitude, frequency, dt, settled.time_s, o.warmup, o.periods, steps);
  std::printf("%-10s %-10s %-9s %-14s %-22s %-9s\n", "run", "particles", "steps", "psteps_per_s",
              "range", "contacts");
  for (long k = 0; k < warm; k += every) system.advance();
  const StateArrays warmed = system.save();
  const EngineConfig& config = scene.dampers.front().engine;
  const int n = system.particle_count();
  auto report = [&](const char* what, const std::vector<double>& walls, const DemEngine& engine,
                    const ContainerKinematics& container) {
    std::vector<double> rates;
    for (double wall : walls) rates.push_back(static_cast<double>(steps) * n / wall);
    const Spread rate = spread(rates);
    std::printf("%-10s %-10d %-9ld %-14.4g %-22s %-9.2f\n", what, n, steps, rate.median,
                range_text(rate).c_str(), contacts_per_particle(engine, config, container));
    std::fflush(stdout);
    return rate.median;
  };
  std::vector<ContainerKinematics> motion;  // the container at the start of each exchange
  std::vector<double> walls;
  for (int r = 0; r < o.repeat; ++r) {
    system.restore(warmed);
    motion.clear();
    const auto start = std::chrono::steady_clock::now();
    for (long k = 0; k < steps; k += every) {
      motion.push_back(system.container_now(0));
      system.advance();
    }
    walls.push_back(seconds_since(start));
  }
  const double coupled =
      report("coupled", walls, *system.engines().front(), system.container_now(0));
  EngineConfig alone = config;
  alone.dt = dt;
  std::unique_ptr<DemEngine> engine;
  walls.clear();
  for (int r = 0; r < o.repeat; ++r) {
    engine = make_engine(alone);
    engine->restore(get_state(warmed, "damper0."));
    const auto start = std::chrono::steady_clock::now();
    for (long k = 0; k < steps; ++k) {
      if (engine->compute(motion[static_cast<std::size_t>(k / every)], dt).flags)
        throw SimulationError("bench scene blew up");
      engine->accept();
    }
    walls.push_back(seconds_since(start));
  }
  const double dem = report("DEM alone", walls, *engine, motion.back());
  std::printf("coupled / DEM alone: %.3f (medians)\n", coupled / dem);
}

}  // namespace

int run_bench(const BenchOptions& o) {
  const Backend backend = o.backend == "cuda" ? Backend::cuda : Backend::cpu;
  if (o.coupling) {
    bench_coupling();
    return 0;
  }
  if (o.rigid) {
    bench_rigid(o);
    return 0;
  }
  // The scenes timed over whole periods (and by --jobs): the boxes, then the pile.
  struct Flow {
    std::string title;
    EngineConfig config;
    Shake shake;
  };
  std::vector<Flow> flows;
  if (o.box)
    for (int n : o.particles)
      flows.push_back({"shaken steel-sphere box: d = 5 mm, E = 2e11 Pa, hertz/history, gravity",
                       bench_config(n, 1, backend, o.steps > 0 ? Fill::lattice : Fill::random),
                       kBoxShake});
  if (o.pile && o.steps == 0)
    flows.push_back(
        {"dense pile (the Saeki damper): 250 spheres d = 5 mm in a 50 mm cube, E = "
         "2e9 Pa, hertz/history, gravity",
         pile_config(backend), kPileShake});
  if (o.steps == 0) {
    for (const Flow& f : flows) bench_flow(f.title.c_str(), f.config, f.shake, o);
    if (o.saeki) bench_saeki(o, backend);
  } else {
    std::printf(
        "# shaken steel-sphere box: d = 5 mm, hertz/history, gravity, dt = 1e-6 s, "
        "lattice start, x = 0.004 sin(2 pi 20 t); set-up included\n");
    std::printf("%-10s %-8s %-9s %-10s %-14s %-16s %-34s %s\n", "particles", "threads", "steps",
                "wall_s", "psteps_per_s", "bytes/particle", "variant", "state_sum");
    for (int n : o.particles) {
      for (int t : o.threads) {
        EngineConfig c = bench_config(n, t, backend);
        long long ps = 0;
        std::size_t bytes = 0;
        double sum = 0;
        const double wall = time_engine(c, o.steps, &ps, 0, &bytes, &sum);
        std::printf("%-10d %-8d %-9ld %-10.3f %-14.4g %-16zu %-34s %.17g\n", n, t, o.steps, wall,
                    static_cast<double>(ps) / wall, bytes, variant_name(c).c_str(), sum);
        std::fflush(stdout);
      }
    }
  }
  if (o.jobs > 0) {
    // Independent scenes side by side (sweep points): the throughput of the whole machine.
    std::printf(
        "\n# %d copies of each scene at once, one thread each (as `pdsim sweep` runs points), %s; "
        "psteps_per_s counts all copies\n",
        o.jobs,
        o.steps > 0 ? "from the lattice, set-up included"
                    : "whole periods from one warmed state, set-up excluded");
    std::printf("%-10s %-8s %-9s %-10s %-14s\n", "particles", "jobs", "steps", "wall_s",
                "psteps_per_s");
    for (const Flow& f : flows) {
      const EngineConfig& c = f.config;
      const int n = static_cast<int>(c.particles.size());
      const long steps = o.steps > 0 ? o.steps : period_steps(o.periods, f.shake, c.dt);
      const Warmed warmed = o.steps > 0 ? Warmed{} : warm_up(c, f.shake, o.warmup);
      std::vector<double> walls(static_cast<std::size_t>(o.jobs));
      std::vector<std::thread> copies;
      std::vector<std::exception_ptr> errors(walls.size());
      for (std::size_t k = 0; k < walls.size(); ++k)
        copies.emplace_back([&, k] {
          try {
            long long ps = 0;
            std::unique_ptr<DemEngine> engine;
            walls[k] = o.steps > 0 ? time_engine(c, steps, &ps)
                                   : time_warmed(c, warmed, steps, f.shake, engine);
          } catch (...) {
            errors[k] = std::current_exception();
          }
        });
      for (auto& copy : copies) copy.join();
      for (const auto& error : errors)
        if (error) std::rethrow_exception(error);
      // The copies ran together: the machine's rate is their work over the longest one's time.
      const double wall = *std::max_element(walls.begin(), walls.end());
      const double total = static_cast<double>(o.jobs) * static_cast<double>(steps) * n;
      std::printf("%-10d %-8d %-9ld %-10.3f %-14.4g\n", n, o.jobs, steps, wall, total / wall);
      std::fflush(stdout);
    }
  }
  if (!o.effects) return 0;
  // Cost of each optional effect, measured side by side in this run (one thread, first count).
  const Effect effects[] = {
      {"full: hertz+history+gravity", NormalModel::hertz, TangentialModel::history, true, false,
       false},
      {"no gravity", NormalModel::hertz, TangentialModel::history, false, false, false},
      {"no friction", NormalModel::hertz, TangentialModel::none, true, false, false},
      {"directional Coulomb", NormalModel::hertz, TangentialModel::directional, true, false, false},
      {"+ rolling resistance", NormalModel::hertz, TangentialModel::history, true, true, false},
      {"linear normal law", NormalModel::linear, TangentialModel::history, true, false, false},
      {"polydisperse radii path", NormalModel::hertz, TangentialModel::history, true, false, true},
  };
  // Each effect changes the dynamics: over ~1e5 steps a frictionless box keeps its energy and
  // collides far more than a frictional one. So every variant starts from the same state (the
  // full model after 0.05 s of shaking: spheres fallen onto the floor and in contact) and runs
  // a few thousand steps, too few to diverge; the best of five repeats is kept.
  const int n = o.particles.front();
  const long settle = 50000, steps = o.steps > 0 ? std::min(o.steps, 5000L) : 5000;
  EngineConfig start = bench_config(n, 1, backend);
  {
    auto engine = make_engine(start);
    shake(*engine, start.dt, 0, settle);
    start.particles = engine->particles();
  }
  std::printf(
      "\n# effect cost: %d particles, 1 thread, best of 5 x %ld steps from one state "
      "(after %ld steps of the full model)\n",
      n, steps, settle);
  std::printf("%-30s %-14s %-10s %s\n", "effect", "psteps_per_s", "relative", "variant");
  double reference = 0;
  for (const Effect& e : effects) {
    EngineConfig c = start;
    c.normal = e.normal;
    c.tangential = e.tangential;
    if (!e.gravity) c.gravity.reset();
    c.rolling = e.rolling;
    if (e.polydisperse) c.radius.back() *= 0.999;  // one smaller sphere selects the radii path
    double best = 0;
    for (int repeat = 0; repeat < 5; ++repeat) {
      long long ps = 0;
      const double wall = time_engine(c, steps, &ps, settle);
      best = std::max(best, static_cast<double>(ps) / wall);
    }
    if (reference == 0) reference = best;
    std::printf("%-30s %-14.4g %-10.3f %s\n", e.name, best, best / reference,
                variant_name(c).c_str());
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace pdsim
