#include "src/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <thread>

#include "io/xdmf.hpp"
#include "src/bed_file.hpp"
#include "src/driver.hpp"
#include "src/format.hpp"
#include "src/frequency_run.hpp"
#include "src/identity.hpp"
#include "src/interrupt.hpp"
#include "src/summary.hpp"
#include "src/sweep.hpp"

namespace pdsim {

std::string output_path(const Deck& deck, const RunOptions& options) {
  if (!options.output.empty()) return options.output;
  if (deck.point > 0)
    return (std::filesystem::path(sweep_folder(deck)) / point_file(deck, deck.point)).string();
  if (!deck.output.file.empty()) return deck.output.file;
  return std::filesystem::path(deck.path).stem().string() + ".h5";
}

void check_output_path(const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty() || path.find('\0') != std::string::npos)
    throw InputError("output file: expected a path without NUL characters, got '" + path + "'");
  std::error_code ignored;  // a path that cannot be examined is treated as absent
  if (fs::is_directory(path, ignored))
    throw InputError(path + ": is a folder; expected the path of an output file");
  const fs::path folder = fs::path(path).parent_path();
  if (!folder.empty() && !fs::is_directory(folder, ignored))
    throw InputError(path + ": the folder " + folder.string() + " does not exist");
  const fs::path place = folder.empty() ? fs::path(".") : folder;
  if (access(place.c_str(), W_OK | X_OK) != 0)
    throw InputError(path + ": the folder " + place.string() + " is not writable");
}

std::string output_beside(const Deck& deck, const std::string& suffix) {
  const std::filesystem::path run = output_path(deck, RunOptions{});
  return (run.parent_path() / (run.stem().string() + suffix)).string();
}

namespace {

// The first fill's scene, how to build any other fill's (fill seeds seed + r of every damper),
// and how many runs go side by side: one per core unless told, the cores shared out.
struct Plan {
  Scene first;
  std::function<Scene(int)> make_scene;
  int jobs = 1;
};

// Runs that can go side by side: the first fills, or with independent frequencies the
// frequencies (each task runs its fills in turn, Driver::run_independent()).
int side_by_side_tasks(const RunPlan& plan) {
  return plan.independent() ? static_cast<int>(plan.points.size()) : plan.first_fills;
}

// The threads a run may use: the scene's (--threads, else solver.threads), else every core.
int total_threads(const Scene& scene) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return scene.threads > 0 ? scene.threads : cores;
}

Plan plan_run(const RunPlan& plan, const Scene& scene, int jobs) {
  const int tasks = side_by_side_tasks(plan);
  const int side_by_side = runs_side_by_side(plan, scene, jobs);
  const int each = tasks > 1 ? std::max(1, total_threads(scene) / side_by_side) : scene.threads;
  // The same scene on fewer threads: not built again (a fill of a million spheres takes
  // seconds, and the CUDA probe more).
  Scene first = scene;
  if (each != scene.threads) {
    first.threads = each;
    for (DamperScene& d : first.dampers) d.engine.threads = each;
  }
  auto make = [base = first](int r) { return scene_of_fill(base, r); };
  return {std::move(first), make, side_by_side};
}

}  // namespace

DeckRecord deck_record(const Deck& deck) {
  DeckRecord r{deck.text, deck.path, deck.title, ""};
  if (deck.point > 0)
    r.sweep_point = std::to_string(deck.point) + ": " + deck.sweep.describe(deck.point);
  return r;
}

int runs_side_by_side(const RunPlan& plan, const Scene& scene, int jobs) {
  return std::max(1, std::min(side_by_side_tasks(plan), jobs > 0 ? jobs : total_threads(scene)));
}

double simulated_time_bound(const RunPlan& plan) {
  if (!plan.steady) return plan.duration * static_cast<double>(plan.points.size());
  double simulated = 0;
  for (const PlanPoint& p : plan.points)
    simulated += plan.most_fills * plan.settle.max_periods / p.frequency;
  return simulated;
}

double memory_estimate_mib(const RunPlan& plan, const Scene& scene) {
  double particles = 0;
  for (const DamperScene& d : scene.dampers) particles += double(d.engine.particles.size());
  // Measured (peak resident size, `/usr/bin/time -v`): a fill of 100,000 and of 300,000 spheres
  // peaks at 4.6 KiB a sphere (its engine, its kept bed and a copy while it is restored), each
  // further fill adds 1.9 KiB (its kept bed); 1,000,000 spheres in two fills at 6.4 KiB, side by
  // side or not (validation/results/memory.md). An engine for each run side by side, and a
  // kept bed for every fill a point may grow to.
  const int engines = runs_side_by_side(plan, scene, 0);
  const int beds = std::max(engines, plan.most_fills);
  double mib =
      std::max(256.0, 64.0 + particles / 1024.0 * (5.0 * engines + 2.0 * (beds - engines)));
  // Particle snapshots are held until the file is written: 11 numbers a particle each.
  if (plan.output.particles_every > 0)
    mib += simulated_time_bound(plan) / plan.output.particles_every * particles * 88.0 / (1 << 20);
  // A CUDA context holds a few hundred MiB of host memory (allowed for, not measured here).
  if (scene.backend == Backend::cuda) mib += 1024.0;
  return mib;
}

std::string memory_shortfall(const RunPlan& plan, const Scene& scene) {
  std::ifstream info("/proc/meminfo");
  double available_kib = 0;
  for (std::string key; info >> key;) {
    if (key == "MemAvailable:") {
      info >> available_kib;
      break;
    }
    info.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  const double need = memory_estimate_mib(plan, scene), have = available_kib / 1024;
  if (!(have > 0) || need <= have) return "";
  return "the run may need up to " + number(need, 3) + " MiB, and " + number(have, 3) +
         " MiB are available now: expect swapping or an out-of-memory kill; fewer particles or "
         "fills (settle.max_realisations) need less";
}

namespace {

// The Driver of `run`'s fills, `jobs` side by side; the beds kept in bed.file read unless
// `resume` (a resumed run's checkpoint holds its first fills' beds, as before its first point).
Driver driver_of(const CompiledRun& run, int jobs, bool quiet, std::string dump_path, bool resume) {
  Plan plan = plan_run(run.plan, run.scene, jobs);
  return Driver(run.record, run.plan,
                resume ? std::nullopt : read_bed_file(run.scene, run.plan, run.bed_where),
                std::move(plan.first), plan.make_scene, plan.jobs, quiet, std::move(dump_path));
}

}  // namespace

Results simulate(const Deck& deck, const Scene& scene, bool quiet, int jobs) {
  const CompiledRun run{deck_record(deck), scene, plan_of(deck, scene), deck.where("bed.file"), {}};
  return driver_of(run, jobs, quiet, "", false).run({}, 0);
}

Identity deck_identity(const Deck& deck, const Scene& scene) {
  return scene_identity(scene, plan_of(deck, scene).bed);
}

Identity deck_identity(const Deck& deck) {
  // Neither threads nor the backend change what the identity holds, and fill 0 is all of the
  // fills it takes.
  return deck_identity(deck, build_scene(deck, 1, Backend::cpu, false));
}

std::string changes_since(const Results& saved, const Deck& deck, const Scene* scene) {
  return changes_since(saved, deck.text,
                       [&] { return scene ? deck_identity(deck, *scene) : deck_identity(deck); });
}

std::string changes_since(const Results& saved, const std::string& text_now,
                          const std::function<Identity()>& now) {
  const auto kept = [](const std::string& key) {
    return key == "title" || key == "solver.threads" || key.rfind("cluster.", 0) == 0;
  };
  std::string out;
  const auto text = saved.meta_text.find("deck");
  for (const DeckChange& c :
       deck_changes(text == saved.meta_text.end() ? "" : text->second, text_now))
    if (!kept(c.key))
      out += (out.empty() ? "" : "; ") + c.key + ": " + c.before + " then, " + c.after + " now";
  // What the deck's text does not hold: a mesh file's triangles, a default of this pdsim.
  const auto id = saved.meta_text.find("identity");
  if (!out.empty() || id == saved.meta_text.end()) return out;
  Identity identity;
  try {
    identity = now();
  } catch (const InputError& e) {
    return std::string("the deck is refused now: ") + e.what();
  }
  return identity_difference(parse_identity(id->second), identity, IdentityScope::bed, "then",
                             "now");
}

// Free space below which a run warns before it starts, bytes.
constexpr std::uintmax_t kLowSpace = 64u << 20;

std::unique_ptr<OutputLock> claim_output(const std::string& path, bool force) {
  namespace fs = std::filesystem;
  // Everything about the output that can be known before computing is checked first.
  std::error_code ignored;  // a path that cannot be examined is treated as absent
  const fs::path folder = fs::path(path).parent_path();
  check_output_path(path);
  if (fs::exists(path, ignored) && !force)
    throw InputError(path + ": output file exists; use --force to overwrite it");
  const fs::path place = folder.empty() ? fs::path(".") : folder;
  // A full disk costs no finished work (the last checkpoint survives), but say it early.
  if (const auto space = fs::space(place, ignored); space.available < kLowSpace)
    std::cerr << "warning: only " << space.available / (1 << 20) << " MiB free for " << path
              << "; a full disk stops the run (exit 2, the last checkpoint kept)\n";
  std::unique_ptr<OutputLock> lock;
  try {
    lock = std::make_unique<OutputLock>(path);
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
  return lock;
}

CompiledRun compile_run(const Deck& deck, int threads, std::optional<Backend> backend,
                        bool every_fill) {
  CompiledRun run{deck_record(deck), build_scene(deck, threads, backend, every_fill), {}, {}, {}};
  run.plan = plan_of(deck, run.scene);
  run.bed_where = deck.where("bed.file");
  run.changes = [deck](const Results& saved, const Scene& scene) {
    return changes_since(saved, deck, &scene);
  };
  return run;
}

void refuse_whole_sweep(const Deck& deck) {
  if (deck.sweep.points() > 0 && deck.point == 0)
    throw InputError(deck.path + ": the deck has a [sweep] table of " +
                     std::to_string(deck.sweep.points()) +
                     " points; run them all with `pdsim sweep`, or one with `pdsim run --point K`");
}

RunReport run_deck(const Deck& deck, const RunOptions& options) {
  const InterruptScope interrupts;
  const std::string path = output_path(deck, options);
  refuse_whole_sweep(deck);
  namespace fs = std::filesystem;
  std::error_code ignored;
  const fs::path folder = fs::path(path).parent_path();
  if (deck.point > 0 && !folder.empty() && path.find('\0') == std::string::npos)
    fs::create_directories(folder, ignored);  // a sweep point's folder
  const std::unique_ptr<OutputLock> lock = claim_output(path, options.force);
  return run_compiled(compile_run(deck, options.threads, options.backend), path, options);
}

RunReport run_compiled(const CompiledRun& run, const std::string& path, const RunOptions& options) {
  const InterruptScope interrupts;
  const std::string partial = path + ".partial";
  namespace fs = std::filesystem;
  const Scene& scene = run.scene;
  if (!scene.warning.empty()) std::cerr << "warning: " << scene.warning << "\n";
  if (const std::string short_of = memory_shortfall(run.plan, scene); !short_of.empty())
    std::cerr << "warning: " << short_of << "\n";
  Driver driver = driver_of(run, options.jobs, options.quiet, path + ".blowup.csv", options.resume);
  if (options.resume) {
    if (!fs::exists(partial))
      throw InputError(partial + ": nothing to resume (no checkpoint of an interrupted run)");
    Results saved = read_results(partial);
    if (const std::string changed = run.changes(saved, scene); !changed.empty())
      throw InputError(partial + ": the deck changed since the interrupted run (" + changed +
                       "); run it anew without --resume");
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
    if (interrupted() && !fs::exists(partial))
      throw Interrupted("interrupted before the first frequency finished; nothing kept");
    if (interrupted())
      throw Interrupted(std::string("interrupted; finished frequencies are in ") + partial +
                        ", continue with --resume");
    throw;
  }
  if (driver.stopped())
    return {partial, "stopped after " + std::to_string(driver.finished()) +
                         " frequencies as asked; continue with --resume"};
  write_results(path, results, true, options.force);
  std::string summary = summary_line(results, path, run.plan);
  if (results.particles) {
    write_xdmf(path, *results.particles);
    summary += "; particles: " + xdmf_path(path) + " (ParaView)";
  }
  return {path, summary};
}

}  // namespace pdsim
