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

// Writes the script (its sbatch command in its comments) and submits the array from the
// current folder (--chdir), with --requeue, then the collect job after it (afterany). Throws
// InputError when sbatch cannot be started, std::runtime_error with sbatch's words when it
// refuses.
SlurmJobs submit_array(const SlurmArray& job);

// What was submitted, for the terminal: "N of TOTAL <pieces> submitted ... as job array A",
// the job B after it writing `result`, how to watch them and how to continue (`again`).
std::string submitted(const SlurmArray& job, const SlurmJobs& ids, std::size_t total,
                      const std::string& pieces, const std::string& result,
                      const std::string& again);

// A word for a bash script: single-quoted, each ' written as '\''.
std::string shell_quoted(const std::string& word);

// This executable's path, for the jobs' scripts.
std::string this_executable();

}  // namespace pdsim
