// pdsim map: a damper characterised once under prescribed sinusoidal motion (the deck's [map]
// grid), so that a host's response can be predicted from it (harmonic balance). Each grid run
// is a prescribed-motion run of the deck's dampers, written to a file of its own beside the map
// (resumable as any run), and the map gathers their first force harmonics into /map.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "src/run.hpp"

namespace pdsim {

struct MapOptions {
  std::string output;  // the map file (default: the deck's output name with "_map.h5")
  int threads = 0;
  int jobs = 0;  // fills and frequencies side by side within a run (0 = one per core)
  std::optional<Backend> backend;
  bool resume = false;  // keep finished runs, continue an interrupted one
  bool force = false;   // run every grid point anew
  bool quiet = false;
  int run = 0;           // run only this grid run (1 to N), as a Slurm task does; 0 = every one
  bool collect = false;  // run nothing: the map from its finished runs
  bool slurm = false;    // submit the runs as a Slurm job array instead
  std::string sbatch;    // more sbatch options for --slurm, after the deck's [cluster] sbatch
};

// One of a map's runs: the deck's dampers moved along `axis` (unit) at its points, each from the
// settled bed or, `stepped`, carried from the one before (an amplitude sweep at one frequency);
// its file, the bed file it reads or keeps, and its label ("run 2 of 6").
struct MapRun {
  std::vector<PlanPoint> points;  // frequency (Hz), amplitude (m), sweep, in the order they run
  Vec3 axis;
  bool stepped = false;
  std::string file, bed_file, label;
};

// The map's runs, in order: one per amplitude over the map's frequencies, or one per
// acceleration and frequency (its amplitude a g / w^2), or stepped, one per frequency through
// its amplitudes; along the structure's direction (a prescribed deck: its motion's axis), their
// files in `folder`. Every run reads the one settled bed (rigid contacts: each its own, its step
// following its motion). Throws InputError for a deck without [map] or [[damper]].
std::vector<MapRun> map_runs(const Deck& deck, const std::string& folder);

// The map's dampers, compiled once for all its runs (`run`: any of them); `every_fill`: as
// build_scene().
DamperModel map_model(const Deck& deck, const MapRun& run, int threads,
                      std::optional<Backend> backend, bool every_fill);

// A map run compiled: `model` (the deck's dampers, map_model()) on a prescribed host, and the
// run's plan; its /meta/deck is the deck's text with a note of the run.
CompiledRun compile_map_run(const DamperModel& model, const Deck& deck, const MapRun& run);

// /map from the runs' /prescribed tables (results[k] is runs[k]'s).
MapTable map_rows(const std::vector<MapRun>& runs, const std::vector<Results>& results);

// `pdsim check`'s lines on the map, every run's scene built (so that a run that would be refused
// is refused now, naming its point).
std::string check_map(const Deck& deck, int threads, std::optional<Backend> backend);

// Runs every grid point not yet finished and writes the map. With options.run only that run
// (skipped when finished, continued from its checkpoint), no map; with options.collect no run,
// the map from the runs when every one has finished (else std::runtime_error naming the others);
// with options.slurm no run: the runs not finished as one Slurm job array (task K runs
// `pdsim map --run K`) and `pdsim map --collect` after it (src/slurm.hpp). Without a map
// written, the report's output is empty.
RunReport run_map(const Deck& deck, const MapOptions& options);

}  // namespace pdsim
