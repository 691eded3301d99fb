// `pdsim sweep`: every point of a deck's [sweep] table, run as separate `pdsim run --point K`
// processes, several at once (small scenes run fastest on one core each, so a sweep uses the
// cores by running points side by side), then one summary table.
#pragma once

#include <optional>
#include <string>

#include "io/deck.hpp"

namespace pdsim {

struct SweepOptions {
  std::string folder;  // default: sweep_folder(deck)
  int jobs = 0;        // points run at once; 0 = one per core, at most the number of points
  int threads = 0;     // threads per point; 0 = the cores shared out among the jobs
  std::optional<Backend> backend;
  bool resume = false;   // keep finished points, resume interrupted ones
  bool force = false;    // rerun every point
  bool status = false;   // say what each point's files say, run nothing
  bool collect = false;  // write summary.csv from the points that have finished, run nothing
  bool ranks = false;    // run only this launcher rank's points (mpirun / srun), see run_sweep
  bool slurm = false;    // submit the points as a Slurm job array instead, see run_sweep
  std::string sbatch;    // more sbatch options for --slurm, after the deck's [cluster] sbatch
};

// Folder of a sweep's files: the deck's output name without ".h5", plus "_sweep".
std::string sweep_folder(const Deck& deck);
// File of sweep point `point` in that folder: "p001.h5" (as many digits as the largest point).
std::string point_file(const Deck& deck, int point);

// Runs the sweep; returns the exit code (0 all points finished, 2 some failed, 130 interrupted).
// Throws InputError before running anything when a point's deck is invalid. With
// options.status or options.collect it runs nothing and reads the sweep's files instead (each
// point finished, running, interrupted, failed or not run, from its file, checkpoint, lock
// and log): --status lists them, --collect writes summary.csv from the finished ones; 0 when
// every point has finished, else 2. With options.ranks a process started by a launcher
// (mpirun, srun: its rank and size from OMPI_COMM_WORLD_RANK/SIZE, PMI_RANK/SIZE or
// SLURM_PROCID/NTASKS; no MPI library) runs the points K with (K - 1) mod size = rank, and
// whichever rank finds every point finished writes summary.csv; 0 when its own points finished.
// With options.slurm it runs nothing here: it writes FOLDER/slurm_array.sh, submits it with
// sbatch as one job array (task K runs point K, resuming its checkpoint when one is there;
// `--jobs` at a time; the threads and memory a point needs; requeued if preempted), then a
// collect job after it (afterany) that writes summary.csv, and prints both job ids. The deck's
// [cluster] sbatch options and options.sbatch go to both jobs. With --resume only the points
// neither finished nor running are submitted; with --force every point's files are removed
// first.
int run_sweep(const Deck& deck, const SweepOptions& options);

// In a point process started by a sweep: asks the kernel for SIGINT when the sweep dies (a
// SIGKILL gives the sweep no chance to pass on its interrupt), so that no point runs on
// unwatched; SIGINT keeps the point's finished frequencies. Does nothing elsewhere.
void follow_sweep();

// Validates every point of a sweep (deck and scene) and lists them, for `pdsim check`.
std::string check_sweep(const Deck& deck, int threads, std::optional<Backend> backend);

}  // namespace pdsim
