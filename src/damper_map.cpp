#include "src/damper_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <optional>
#include <sstream>

#include "io/excitation.hpp"
#include "pdsim_version.hpp"
#include "src/identity.hpp"
#include "src/interrupt.hpp"
#include "src/format.hpp"
#include "src/run_plan.hpp"
#include "src/slurm.hpp"

namespace pdsim {

namespace fs = std::filesystem;

namespace {

// The runs' folder beside the map: "OUT_map.h5" -> "OUT_map_runs".
std::string runs_folder(const std::string& map) {
  const fs::path p(map);
  return (p.parent_path() / (p.stem().string() + "_runs")).string();
}

// A map run's excitation: the deck's dampers moved along the run's axis by X sin(2 pi f t) at its
// points (no structure), each from the settled bed or, stepped, carried from the one before.
ExcitationSpec run_excitation(const Deck& deck, const MapRun& run) {
  ExcitationSpec x;
  x.kind = ExcitationKind::prescribed;
  x.motion.axis = run.axis;
  x.motion.amplitude = run.points.front().amplitude;
  x.motion.frequency = run.points.front().frequency;
  for (const PlanPoint& p : run.points) {
    x.frequencies.push_back(p.frequency);
    x.sweeps.push_back(p.sweep);
    if (run.stepped) x.amplitudes.push_back(p.amplitude);
  }
  x.frequencies_key = "map.frequencies";
  x.settle = deck.excitation.settle;
  x.duration = deck.map.duration;
  x.start = run.stepped ? FrequencyStart::carried : FrequencyStart::independent;
  return x;
}

// A map run's /meta/deck: the deck's text with a note of the run (a finished run is compared
// with it).
std::string run_text(const Deck& deck, const MapRun& run) {
  std::ostringstream note;
  note.precision(17);
  note << "\n# pdsim map: " << run.label << ": prescribed motion along [" << run.axis.x << ", "
       << run.axis.y << ", " << run.axis.z << "], ";
  if (run.stepped) {
    note << "at " << run.points.front().frequency << " Hz, amplitudes (m, in this order)";
    for (const PlanPoint& p : run.points) note << " " << p.amplitude;
  } else {
    note << "amplitude " << run.points.front().amplitude << " m";
  }
  return deck.text + note.str() + "\n";
}

// The identity of a map run's dampers and bed (fill 0 is all it takes).
Identity run_identity(const Deck& deck, const MapRun& run) {
  const CompiledRun c = compile_map_run(map_model(deck, run, 1, Backend::cpu, false), deck, run);
  return scene_identity(c.scene, c.plan.bed);
}

// The amplitude (m) of a peak acceleration of g (in kStandardGravity) at f Hz.
double amplitude_of(double g, double f) {
  const double w = 2 * kPi * f;
  return g * kStandardGravity / (w * w);
}

// The map's amplitudes at frequency f, ascending (m).
std::vector<double> amplitudes_at(const MapSpec& m, double f) {
  std::vector<double> a = m.amplitudes;
  for (double g : m.accelerations) a.push_back(amplitude_of(g, f));
  std::sort(a.begin(), a.end());
  return a;
}

}  // namespace

std::vector<MapRun> map_runs(const Deck& deck, const std::string& folder) {
  const MapSpec& m = deck.map;
  if (!m.given())
    throw InputError(deck.path +
                     ": the deck has no [map] table (amplitudes or accelerations, "
                     "and frequencies); see io/decks.md");
  if (deck.dampers.empty()) throw InputError(deck.path + ": the deck has no [[damper]] to map");
  Vec3 axis;
  if (traits(deck.excitation.kind).moves_containers)
    axis = deck.excitation.motion.axis;
  else  // an SDOF's or a beam's direction (a beam's slope turning the container is left out)
    axis = deck.structure.direction;
  auto file = [&](std::size_t k) {
    char name[32];
    std::snprintf(name, sizeof name, "m%03zu.h5", k + 1);
    return (fs::path(folder) / name).string();
  };
  // One run per amplitude over the frequencies, or per acceleration and frequency; stepped, one
  // per frequency through its amplitudes.
  struct Points {
    std::vector<double> frequencies, amplitudes;
    std::vector<int> sweeps;
  };
  std::vector<Points> points;
  if (m.steps != MapSteps::independent) {
    for (double f : m.frequencies) {
      Points& p = points.emplace_back();
      p.amplitudes = amplitudes_at(m, f);
      p.sweeps.assign(p.amplitudes.size(), 1);
      if (m.steps == MapSteps::both) {  // back down from the top, as a frequency sweep "both"
        const std::vector<double> up = p.amplitudes;
        p.amplitudes.insert(p.amplitudes.end(), up.rbegin(), up.rend());
        p.sweeps.resize(p.amplitudes.size(), -1);
      }
      p.frequencies.assign(p.amplitudes.size(), f);
    }
  } else if (!m.amplitudes.empty()) {
    for (double a : m.amplitudes)
      points.push_back({m.frequencies, std::vector<double>(m.frequencies.size(), a),
                        std::vector<int>(m.frequencies.size(), 1)});
  } else {
    for (double g : m.accelerations)
      for (double f : m.frequencies) points.push_back({{f}, {amplitude_of(g, f)}, {1}});
  }
  std::vector<MapRun> runs;
  for (std::size_t k = 0; k < points.size(); ++k) {
    MapRun& run = runs.emplace_back();
    const Points& p = points[k];
    for (std::size_t i = 0; i < p.frequencies.size(); ++i)
      run.points.push_back({p.frequencies[i], p.amplitudes[i], p.sweeps[i]});
    run.axis = axis;
    run.stepped = m.steps != MapSteps::independent;
    run.file = file(k);
    run.label = "run " + std::to_string(k + 1) + " of " + std::to_string(points.size());
    // The runs share one settled bed (its identity checks that it is theirs). A rigid contact's
    // step follows each run's motion (src/scene.cpp), and its bed with it: each run keeps its
    // own, named for the run ("bed_m001.h5", or the deck's bed.file with "_m001" before its
    // extension).
    const fs::path out(run.file), bed(deck.bed.file);
    const std::string stem = out.stem().string();
    run.bed_file =
        bed.empty() ? (out.parent_path() /
                       (deck.contact.nonsmooth ? "bed_" + stem + ".h5" : std::string("bed.h5")))
                          .string()
        : deck.contact.nonsmooth
            ? (bed.parent_path() / (bed.stem().string() + "_" + stem + bed.extension().string()))
                  .string()
            : deck.bed.file;
  }
  return runs;
}

DamperModel map_model(const Deck& deck, const MapRun& run, int threads,
                      std::optional<Backend> backend, bool every_fill) {
  return compile_dampers(deck, threads, backend,
                         every_fill ? most_fills(run_excitation(deck, run)) : 1);
}

CompiledRun compile_map_run(const DamperModel& model, const Deck& deck, const MapRun& run) {
  const ExcitationSpec x = run_excitation(deck, run);
  CompiledRun c;
  c.record = deck_record(deck);
  c.record.text = run_text(deck, run);
  c.scene = place_dampers(model, deck, x, StructureSpec{});
  BedSpec bed = deck.bed;
  bed.file = run.bed_file;
  OutputSpec output = deck.output;
  output.file = run.file;
  output.particles_every = 0;
  output.energy = false;
  c.plan = plan_of(x, bed, output, c.scene);
  c.bed_where = deck.where("bed.file");
  c.changes = [text = c.record.text, bed = c.plan.bed](const Results& saved, const Scene& scene) {
    return changes_since(saved, text, [&] { return scene_identity(scene, bed); });
  };
  return c;
}

MapTable map_rows(const std::vector<MapRun>& runs, const std::vector<Results>& results) {
  MapTable m;
  for (std::size_t k = 0; k < runs.size(); ++k) {
    const bool stepped = runs[k].stepped;
    const PrescribedTable& p = results[k].prescribed;
    // Runs written before /prescribed had amplitude and sweep: the run's points say them.
    const bool old = p.amplitude.size() != p.frequency.size();
    for (std::size_t i = 0; i < p.frequency.size(); ++i) {
      const double w = 2 * kPi * p.frequency[i];
      const double X = old ? runs[k].points.at(i).amplitude : p.amplitude[i];
      m.sweep.push_back(!stepped ? 0 : old ? runs[k].points.at(i).sweep : p.sweep[i]);
      const double F = p.force_amplitude[i], dF = p.force_amplitude_ci[i];
      const double phi = p.force_phase[i], dphi = p.force_phase_ci[i];
      const double c = std::cos(phi), s = std::sin(phi);
      m.frequency.push_back(p.frequency[i]);
      m.amplitude.push_back(X);
      m.acceleration.push_back(X * w * w / kStandardGravity);
      m.force_amplitude.push_back(F);
      m.force_amplitude_ci.push_back(dF);
      m.force_phase.push_back(phi);
      m.force_phase_ci.push_back(dphi);
      // F1 / X = (F / X) e^(i phi) = w^2 m_eff - i w c_eff; intervals to first order.
      m.effective_mass.push_back(F * c / (X * w * w));
      m.effective_mass_ci.push_back(std::hypot(c * dF, F * s * dphi) / (X * w * w));
      m.effective_damping.push_back(-F * s / (X * w));
      m.effective_damping_ci.push_back(std::hypot(s * dF, F * c * dphi) / (X * w));
      m.dissipated_power.push_back(p.dissipated_power[i]);
      m.dissipated_power_ci.push_back(p.dissipated_power_ci[i]);
      m.periods.push_back(p.periods[i]);
      m.converged.push_back(p.converged[i]);
      m.realisations.push_back(p.realisations[i]);
    }
  }
  return m;
}

std::string check_map(const Deck& deck, int threads, std::optional<Backend> backend) {
  const std::vector<MapRun> runs = map_runs(deck, "runs");
  double low = runs.front().points.front().amplitude, high = low;
  std::size_t points = 0;
  std::optional<DamperModel> model;  // every run's dampers
  // Rigid contacts: each run's step and tolerance follow its motion (src/scene.cpp).
  double dt_low = 1e300, dt_high = 0, tolerance_low = 1e300, tolerance_high = 0;
  for (const MapRun& run : runs) {
    for (const PlanPoint& p : run.points)
      low = std::min(low, p.amplitude), high = std::max(high, p.amplitude);
    points += run.points.size();
    try {
      if (!model) model = map_model(deck, run, threads, backend, true);
      const Scene scene = compile_map_run(*model, deck, run).scene;
      if (const auto& n = scene.dampers.front().engine.nonsmooth) {
        dt_low = std::min(dt_low, scene.dt), dt_high = std::max(dt_high, scene.dt);
        tolerance_low = std::min(tolerance_low, n->tolerance);
        tolerance_high = std::max(tolerance_high, n->tolerance);
      }
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + " (in [map], " +
                       (!run.stepped
                            ? "at amplitude " + number(run.points.front().amplitude) + " m)"
                            : "at " + number(run.points.front().frequency) + " Hz)"));
    }
  }
  const MapSpec& m = deck.map;
  const Vec3 axis = runs.front().axis;
  std::ostringstream s;
  s << "map: " << (m.amplitudes.empty() ? m.accelerations.size() : m.amplitudes.size())
    << (m.amplitudes.empty() ? " accelerations" : " amplitudes") << " x " << m.frequencies.size()
    << " frequencies" << (m.steps == MapSteps::both ? " x 2 ways" : "") << " = " << points
    << " points in " << runs.size() << " runs; prescribed motion along [" << axis.x << ", "
    << axis.y << ", " << axis.z << "], amplitude " << number(low) << " to " << number(high) << " m"
    << (m.steps == MapSteps::both ? ", stepped up and down at each frequency"
        : m.steps == MapSteps::up ? ", stepped up at each frequency"
                                  : ", each point from the settled bed")
    << "\n";
  if (dt_high > 0)
    s << "map runs, rigid contacts: the step " << number(dt_low) << " to " << number(dt_high)
      << " s and the tolerance " << number(tolerance_low) << " to " << number(tolerance_high)
      << " m/s, each run's following its motion"
      << (m.steps != MapSteps::independent
              ? "; a stepped run's tolerance follows its largest amplitude (set "
                "contact.tolerance for its smallest)"
              : "")
      << "\n";
  return s.str();
}

namespace {

// Removes the beds pdsim named for the runs (the shared bed.h5, or each rigid run's own); a
// bed.file the deck names is the user's, refused by name when it no longer fits.
void remove_run_beds(const Deck& deck, const std::vector<MapRun>& runs) {
  std::error_code ignored;
  if (deck.bed.file.empty())
    for (const MapRun& run : runs) fs::remove(run.bed_file, ignored);
}

// A grid run's results when its file holds them (of this run of this deck), else nothing.
std::optional<Results> finished_run(const Deck& deck, const MapRun& run) {
  std::error_code ignored;
  if (!fs::exists(run.file, ignored)) return std::nullopt;
  Results done = read_results(run.file);
  if (const std::string changed =
          changes_since(done, run_text(deck, run), [&] { return run_identity(deck, run); });
      !changed.empty())
    throw InputError(run.file + ": a run of another map (" + changed +
                     "); run the map anew with --force");
  return done;
}

// Runs grid run k (0-based) of `runs` into its file, from its checkpoint with `resume`; `model`
// gives the map's dampers (compiled once, when first asked).
void run_grid_run(const Deck& deck, const std::vector<MapRun>& runs, std::size_t k,
                  const MapOptions& options, bool resume, const std::string& folder,
                  const std::function<const DamperModel&()>& model) {
  const MapRun& run = runs[k];
  const std::string& file = run.file;
  std::error_code ignored;
  RunOptions o;
  o.output = file;
  o.resume = resume && fs::exists(file + ".partial", ignored);
  o.force = options.force;
  o.quiet = options.quiet;
  o.threads = options.threads;
  o.jobs = options.jobs;
  o.backend = options.backend;
  if (!options.quiet)
    std::cerr << "map run " << k + 1 << " of " << runs.size() << ": "
              << (!run.stepped ? "amplitude " + number(run.points.front().amplitude) + " m"
                               : number(run.points.front().frequency) + " Hz, amplitudes stepped")
              << " -> " << file << (o.resume ? ", from its checkpoint" : "") << "\n";
  try {
    const InterruptScope interrupts;
    refuse_whole_sweep(deck);
    const std::unique_ptr<OutputLock> lock = claim_output(file, o.force);
    run_compiled(compile_map_run(model(), deck, run), file, o);
  } catch (const Interrupted& e) {
    throw Interrupted(std::string(e.what()) + "; finished map runs are in " + folder +
                      ", continue the map with pdsim map --resume");
  } catch (const InputError& e) {
    if (fs::exists(file, ignored) && !resume && !options.force)
      throw InputError(std::string(e.what()) +
                       " (a map run left by an earlier map: continue it with --resume, or "
                       "run the map anew with --force)");
    throw;
  }
}

// --slurm: the runs not finished as a job array, `pdsim map --collect` after it.
RunReport submit_map(const Deck& deck, const MapOptions& options, const std::string& path,
                     const std::string& folder, const std::vector<MapRun>& runs) {
  const int threads = options.threads > 0 ? options.threads : std::max(1, deck.solver.threads);
  SlurmArray job;
  job.script = (fs::path(folder) / "slurm_array.sh").string();
  refuse_if_queued(job.script);
  job.options = sbatch_options(deck.cluster.sbatch, "[cluster] sbatch");
  for (const auto& option : sbatch_options(options.sbatch, "--sbatch"))
    job.options.push_back(option);
  std::vector<std::string> files;
  std::vector<bool> finished;
  for (const MapRun& run : runs) {
    files.push_back(run.file);
    finished.push_back(!options.force && options.resume && finished_run(deck, run));
  }
  std::vector<int> running;
  job.tasks = pieces_to_submit(files, finished, options.resume, options.force, running);
  std::error_code ignored;
  if (options.force) {  // the map and the beds pdsim named for its runs are made anew with them
    fs::remove(path, ignored);
    remove_run_beds(deck, runs);
  }
  std::string note;
  for (int k : running) note += (note.empty() ? "runs " : ", ") + std::to_string(k);
  if (!note.empty()) note += " are running and are not submitted\n";
  const std::string map = shell_quoted(this_executable()) + " map " + shell_quoted(deck.path) +
                          " --output " + shell_quoted(path);
  if (job.tasks.empty())
    return {"",
            note + "nothing to submit: " + pdsim_command("map", deck.path, path, "", " --collect") +
                " writes the map once every run has finished"};
  const DamperModel model = map_model(deck, runs.front(), threads, options.backend, true);
  for (int k : job.tasks) {
    const CompiledRun run = compile_map_run(model, deck, runs[static_cast<std::size_t>(k - 1)]);
    job.memory_mib = std::max(job.memory_mib, memory_estimate_mib(run.plan, run.scene));
  }
  job.name = "pdsim-" + fs::path(path).stem().string();
  job.threads = threads;
  job.log = (fs::path(folder) / "m%3a.log").string();
  job.body = "exec " + map + " --run \"$SLURM_ARRAY_TASK_ID\" --threads " +
             std::to_string(threads) + " --quiet" +
             (options.jobs > 0 ? " --jobs " + std::to_string(options.jobs) : std::string()) +
             (options.backend ? std::string(" --backend ") + backend_name(*options.backend)
                              : std::string()) +
             "\n";
  job.collect = map + " --collect --quiet";
  job.collect_log = (fs::path(folder) / "collect.log").string();
  const SlurmJobs ids = submit_array(job);
  return {"", note + "map: " +
                  submitted(
                      job, ids, runs.size(), "runs", path,
                      pdsim_command("map", deck.path, path, options.sbatch, " --slurm --resume"))};
}

}  // namespace

RunReport run_map(const Deck& deck, const MapOptions& options) {
  const std::string path = options.output.empty() ? output_beside(deck, "_map.h5") : options.output;
  const std::string folder = runs_folder(path);
  const std::vector<MapRun> runs = map_runs(deck, folder);
  if (!options.slurm && !options.sbatch.empty()) throw InputError("--sbatch: only with --slurm");
  if (options.slurm && (options.run > 0 || options.collect))
    throw InputError(std::string("--slurm and ") + (options.run > 0 ? "--run" : "--collect") +
                     ": choose one (--slurm submits the runs)");
  if (options.run > 0 && options.collect) throw InputError("--run and --collect: choose one");
  if (options.run > static_cast<int>(runs.size()))
    throw InputError("--run " + std::to_string(options.run) + ": the map has runs 1 to " +
                     std::to_string(runs.size()));
  std::error_code ignored;
  const bool whole = options.run == 0 && !options.collect;  // runs every run, then the map
  if (whole && fs::exists(path, ignored) && !options.force)
    throw InputError(path + ": map file exists; use --force to run the map anew");
  if (!fs::exists(folder, ignored)) {
    const fs::path parent = fs::path(folder).parent_path();
    if (!parent.empty() && !fs::is_directory(parent, ignored))
      throw InputError(path + ": the folder " + parent.string() + " does not exist");
    fs::create_directories(folder, ignored);
  }
  if (options.slurm) return submit_map(deck, options, path, folder, runs);
  std::optional<DamperModel> compiled;
  const auto model = [&]() -> const DamperModel& {
    if (!compiled) compiled = map_model(deck, runs.front(), options.threads, options.backend, true);
    return *compiled;
  };
  if (options.run > 0) {  // a Slurm task: its run, kept when finished, else continued
    const auto k = static_cast<std::size_t>(options.run - 1);
    if (finished_run(deck, runs[k])) return {"", runs[k].file + ": finished earlier, kept"};
    run_grid_run(deck, runs, k, options, true, folder, model);
    return {"", "map run " + std::to_string(options.run) + " of " + std::to_string(runs.size()) +
                    " finished: " + runs[k].file};
  }
  // The beds of the runs are settled anew with them.
  if (options.force && whole) remove_run_beds(deck, runs);
  std::vector<Results> results;
  std::string missing;
  for (std::size_t k = 0; k < runs.size(); ++k) {
    std::optional<Results> done;
    if ((options.resume && !options.force) || options.collect) done = finished_run(deck, runs[k]);
    if (!done && options.collect) {
      missing += (missing.empty() ? "" : ", ") + std::to_string(k + 1);
      continue;
    }
    if (!done) {
      run_grid_run(deck, runs, k, options, options.resume && !options.force, folder, model);
      done = read_results(runs[k].file);
    }
    results.push_back(std::move(*done));
  }
  if (!missing.empty())
    throw std::runtime_error("the map's runs " + missing + " of " + std::to_string(runs.size()) +
                             " have not finished (their files in " + folder + "); no map written");

  Results map;
  map.meta_text = results.front().meta_text;
  map.meta_numbers = results.front().meta_numbers;
  map.meta_text["deck"] = deck.text;
  map.meta_text["deck_path"] = deck.path;
  map.meta_text["identity"] = identity_text(run_identity(deck, runs.front()));
  map.meta_text["version"] = std::string(PDSIM_VERSION) + " (" + PDSIM_GIT + ")";
  map.meta_text.erase("coupling");  // a prescribed motion couples nothing
  for (Results& r : results)
    map.meta_numbers["fills_used"] =
        std::max(map.meta_numbers["fills_used"], r.meta_numbers["fills_used"]);
  for (const char* sum : {"wall_time_s", "particle_steps", "simulated_time_s"}) {
    double total = 0;
    for (Results& r : results) total += r.meta_numbers[sum];
    map.meta_numbers[sum] = total;
  }
  map.map = map_rows(runs, results);
  write_results(path, map, true, true);

  const MapTable& m = map.map;
  int converged = 0;
  for (int c : m.converged) converged += c;
  std::ostringstream s;
  s << "map: " << m.frequency.size() << " points (" << converged << " converged), " << runs.size()
    << " runs in " << folder << "; wall time " << number(map.meta_numbers["wall_time_s"]) << " s";
  return {path, s.str()};
}

}  // namespace pdsim
