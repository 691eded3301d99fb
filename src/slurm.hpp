// Submitting work to Slurm (`pdsim sweep --slurm`, `pdsim map --slurm`): one job array whose
// task K runs a piece of the work, and a collect job after it, both through sbatch. pdsim needs
// no Slurm library, only sbatch on PATH.
#pragma once

#include <string>
#include <vector>

namespace pdsim {

struct SlurmArray {
  std::string name;                  // job name; the collect job's is name + "-collect"
  std::vector<int> tasks;            // array indices, ascending
  int at_once = 0;                   // tasks running at once at most (%N); 0 = as Slurm allows
  int threads = 1;                   // --cpus-per-task
  double memory_mib = 0;             // --mem
  std::string log;                   // a task's log, with %a (--output)
  std::string script;                // where the array's script is written
  std::string body;                  // its commands ($SLURM_ARRAY_TASK_ID is the task)
  std::string collect;               // the collect job's command (--wrap)
  std::string collect_log;           // its log
  std::vector<std::string> options;  // the user's sbatch options ([cluster], --sbatch), last
};

struct SlurmJobs {
  std::string array, collect;  // job ids
};

// Which of the pieces of work (sweep points, map runs) whose outputs are `files` a submission
// sends: every one not `finished`, except, with `resume`, those running (their output's lock
// held: listed in `running`). Everything is checked before anything is removed: a running piece
// without `resume`, or a file or checkpoint left without `resume` or `force`, is refused; with
// `force` the pieces' files and checkpoints are then removed. Returns 1-based indices.
std::vector<int> pieces_to_submit(const std::vector<std::string>& files,
                                  const std::vector<bool>& finished, bool resume, bool force,
                                  std::vector<int>& running);

// Refuses a submission while the job array last submitted from `script` (its id kept beside it)
// is still in Slurm's queue: its pending tasks would run the same pieces twice.
void refuse_if_queued(const std::string& script);

// Writes the script (its sbatch command in its comments) and submits the array from the
// current folder (--chdir), with --requeue, then the collect job after it (afterany). Throws
// InputError when sbatch cannot be started, std::runtime_error with sbatch's words when it
// refuses.
SlurmJobs submit_array(const SlurmArray& job);

// What was submitted, for the terminal: "N of TOTAL <pieces> submitted ... as job array A",
// the job B after it writing `result`, how to watch them and how to continue (`again`, a
// command).
std::string submitted(const SlurmArray& job, const SlurmJobs& ids, std::size_t total,
                      const std::string& pieces, const std::string& result,
                      const std::string& again);

// How to carry on with a submitted sweep or map: "pdsim COMMAND 'DECK' -o 'OUTPUT'", then
// --sbatch 'SBATCH' when given, then `tail`.
std::string pdsim_command(const std::string& command, const std::string& deck,
                          const std::string& output, const std::string& sbatch,
                          const std::string& tail);

// A word for a bash script: single-quoted, each ' written as '\''.
std::string shell_quoted(const std::string& word);

// This executable's path, for the jobs' scripts.
std::string this_executable();

}  // namespace pdsim
