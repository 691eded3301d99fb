// pdsim command line: run, sweep, check, modes, bench. User errors exit 1 with the message;
// simulation failures exit 2; an interrupted run exits 130.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "pdsim_version.hpp"
#include "src/bench.hpp"
#include "src/check_report.hpp"
#include "src/damper_map.hpp"
#include "src/predict.hpp"
#include "src/run.hpp"
#include "src/sweep.hpp"
#include "structure/structure.hpp"

namespace {

std::optional<pdsim::Backend> parse_backend(const std::string& name) {
  if (name.empty()) return std::nullopt;
  if (name == "cpu") return pdsim::Backend::cpu;
  if (name == "cuda") return pdsim::Backend::cuda;
  if (name == "auto") return pdsim::Backend::automatic;
  throw pdsim::InputError("--backend: expected cpu, cuda or auto, got '" + name + "'");
}

}  // namespace

// Ranges that print as what they mean ("not in range 1 to 4096"), not as 0 to 1.8e308.
const CLI::Range kThreads(1, 4096);
const CLI::Range kCount(1, 1'000'000'000);

int main(int argc, char** argv) {
  CLI::App app{"pdsim: particle damper simulator (DEM particles coupled to a structure)"};
  app.set_version_flag("--version", std::string("pdsim ") + PDSIM_VERSION + " (" + PDSIM_GIT + ")");
  app.require_subcommand(1);

  std::string deck_path, output, backend;
  pdsim::RunOptions options;
  auto* run = app.add_subcommand("run", "run a deck and write its HDF5 results");
  run->add_option("deck", deck_path, "input deck (TOML)")->required();
  run->add_option("-o,--output", output, "output file (default: output.file of the deck)");
  run->add_option("--threads", options.threads, "CPU threads (default: all)")->check(kThreads);
  run->add_option("--jobs", options.jobs,
                  "runs side by side: independent frequencies, realisations (default: one per "
                  "core, the threads shared out)")
      ->check(kCount);
  run->add_option("--backend", backend, "cpu, cuda or auto (default: the deck's solver.backend)");
  run->add_flag("--resume", options.resume, "continue an interrupted run from its checkpoint");
  run->add_flag("--force", options.force, "overwrite an existing output file");
  run->add_flag("--quiet", options.quiet, "no progress lines");
  run->add_option("--stop-after", options.stop_after,
                  "stop after N frequencies, keeping the checkpoint for --resume")
      ->check(kCount);
  int point = 0;
  double snapshots = 0;  // s between particle snapshots (--snapshots), 0 = the deck's
  run->add_option("--snapshots", snapshots,
                  "write particle snapshots every S seconds, for ParaView (as the deck's [output] "
                  "particles = { every = S })")
      ->check(CLI::PositiveNumber);
  run->add_option("--point", point, "run one point of the deck's [sweep] table (1 to N)")
      ->check(kCount);

  pdsim::SweepOptions sweep_options;
  auto* sweep = app.add_subcommand(
      "sweep", "run every point of the deck's [sweep] table, several at once, and tabulate them");
  sweep->add_option("deck", deck_path, "input deck (TOML) with a [sweep] table")->required();
  sweep->add_option("-o,--output", sweep_options.folder,
                    "folder for the points' files (default: the deck's output name + _sweep)");
  sweep->add_option("--jobs", sweep_options.jobs, "points run at once (default: one per core)")
      ->check(kCount);
  sweep
      ->add_option("--threads", sweep_options.threads,
                   "CPU threads per point (default: the cores shared among the jobs; with "
                   "--slurm, the deck's solver.threads or 1)")
      ->check(kThreads);
  sweep->add_option("--backend", backend, "cpu, cuda or auto (default: the deck's)");
  sweep->add_flag("--resume", sweep_options.resume,
                  "keep finished points and continue interrupted ones");
  sweep->add_flag("--force", sweep_options.force, "rerun every point, overwriting its file");
  sweep->add_flag("--status", sweep_options.status,
                  "run nothing: each point finished, running, interrupted, failed or not run");
  sweep->add_flag("--ranks", sweep_options.ranks,
                  "under mpirun -np N or srun -n N: this rank's points only; the last writes the "
                  "summary");
  sweep->add_flag("--slurm", sweep_options.slurm,
                  "submit the points as a Slurm job array, and a job after it that writes the "
                  "summary; --jobs caps how many run at once");
  sweep->add_option("--sbatch", sweep_options.sbatch,
                    "with --slurm: more sbatch options, quoted as one (\"--partition=short "
                    "--time=2:00:00\"), after the deck's [cluster] sbatch");
  sweep->add_flag("--collect", sweep_options.collect,
                  "run nothing: summary.csv from the points that have finished, naming the rest");

  pdsim::MapOptions map_options;
  auto* map = app.add_subcommand(
      "map", "characterise the deck's dampers under prescribed motion over its [map] grid");
  map->add_option("deck", deck_path, "input deck (TOML) with a [map] table")->required();
  map->add_option("-o,--output", map_options.output,
                  "map file (default: the deck's output name with _map.h5; its runs beside it in "
                  "a _runs folder)");
  map->add_option("--threads", map_options.threads, "CPU threads (default: all)")->check(kThreads);
  map->add_option("--jobs", map_options.jobs,
                  "fills and frequencies side by side within a run (default: one per core)")
      ->check(kCount);
  map->add_option("--backend", backend, "cpu, cuda or auto (default: the deck's)");
  map->add_flag("--resume", map_options.resume,
                "keep finished runs and continue an interrupted one");
  map->add_flag("--force", map_options.force, "run every grid point anew, overwriting");
  map->add_flag("--quiet", map_options.quiet, "no progress lines");
  map->add_option("--run", map_options.run,
                  "run only this grid run (1 to N), kept when finished, else continued from its "
                  "checkpoint; no map (a Slurm task)")
      ->check(kCount);
  map->add_flag("--collect", map_options.collect,
                "run nothing: the map from its runs, once every one has finished");
  map->add_flag("--slurm", map_options.slurm,
                "submit the runs as a Slurm job array, and a job after it that writes the map");
  map->add_option("--sbatch", map_options.sbatch,
                  "with --slurm: more sbatch options, quoted as one, after the deck's [cluster] "
                  "sbatch");

  pdsim::PredictOptions predict_options;
  auto* predict = app.add_subcommand(
      "predict", "the deck's FRF from a damper map by harmonic balance (every branch)");
  predict
      ->add_option("deck", deck_path,
                   "input deck (TOML): a structure with one damper under a stepped sine")
      ->required();
  predict
      ->add_option("--map", predict_options.maps,
                   "the map file (pdsim map); several, of one damper, are read as one map")
      ->required();
  predict->add_option("-o,--output", predict_options.output,
                      "output file (default: the deck's output name with _hb.h5)");
  predict->add_flag("--force", predict_options.force, "overwrite an existing output file");

  auto* check = app.add_subcommand("check", "validate a deck and print derived quantities");
  check->add_option("deck", deck_path, "input deck (TOML)")->required();

  auto* modes = app.add_subcommand("modes", "print the structure's natural frequencies");
  modes->add_option("deck", deck_path, "input deck (TOML)")->required();
  int mode_count = 10;
  modes->add_option("-n,--count", mode_count, "how many modes")->check(kCount);

  pdsim::BenchOptions bench_options;
  auto* bench = app.add_subcommand("bench", "measure particle-steps per second");
  add_bench_options(*bench, bench_options);

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);  // prints the message and the usage
    return 1;     // bad input, as for a deck (README)
  }
  try {
    if (*bench) return pdsim::run_bench(bench_options);
    pdsim::Deck deck = pdsim::load_deck(deck_path);
    if (*sweep) {
      sweep_options.backend = parse_backend(backend);
      return pdsim::run_sweep(deck, sweep_options);
    }
    if (*map) {
      map_options.backend = parse_backend(backend);
      const pdsim::RunReport report = pdsim::run_map(deck, map_options);
      if (!report.output.empty()) std::cout << "wrote " << report.output << "\n";
      std::cout << report.summary << "\n";
      return 0;
    }
    if (*predict) {
      const pdsim::RunReport report = pdsim::run_predict(deck, predict_options);
      std::cout << "wrote " << report.output << "\n" << report.summary << "\n";
      return 0;
    }
    if (point > 0) deck = pdsim::sweep_point(deck, point);
    if (snapshots > 0) deck = pdsim::with_snapshots(std::move(deck), snapshots);
    if (*modes) {
      if (deck.structure.kind == pdsim::StructureKind::none)
        throw pdsim::InputError(deck.path + ": the deck has no [structure]");
      const auto f = pdsim::structure_frequencies(deck);
      std::cout << pdsim::format_modes(f, mode_count);
      return 0;
    }
    options.output = output;
    options.backend = parse_backend(backend);
    if (*check) {
      const pdsim::Scene scene = pdsim::build_scene(deck, options.threads, options.backend);
      std::cout << pdsim::check_report(deck, scene);
      if (deck.sweep.points() > 0 && deck.point == 0)
        std::cout << pdsim::check_sweep(deck, options.threads, options.backend);
      if (deck.map.given()) std::cout << pdsim::check_map(deck, options.threads, options.backend);
      // What a queued run would trip over only when it starts (a sweep makes its own folder).
      if (deck.sweep.points() == 0 || deck.point > 0) {
        const std::string out = pdsim::output_path(deck, options);
        if (deck.point == 0) pdsim::check_output_path(out);
        if (std::filesystem::exists(out))
          std::cout << "note: " << out
                    << " exists: pdsim run needs --force (or --resume where OUT.partial is)\n";
      }
      std::cout << "deck OK\n";
      return 0;
    }
    pdsim::follow_sweep();
    const pdsim::RunReport report = pdsim::run_deck(deck, options);
    std::cout << "wrote " << report.output << "\n" << report.summary << "\n";
    return 0;
  } catch (const pdsim::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const pdsim::Interrupted& e) {
    std::cerr << "simulation failed: " << e.what() << "\n";
    return 130;
  } catch (const pdsim::SimulationError& e) {
    std::cerr << "simulation failed: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  }
}
