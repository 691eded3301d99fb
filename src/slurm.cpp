#include "src/slurm.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "io/results.hpp"
#include "kernels/errors.hpp"

extern char** environ;

namespace pdsim {
namespace {

namespace fs = std::filesystem;

// Runs a program found on PATH; returns its exit code (-1: it could not start) and what it
// printed, standard output and error together.
std::pair<int, std::string> run_program(std::vector<std::string> args) {
  int fd[2];
  if (pipe(fd) != 0) throw SimulationError(std::string("pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fd[1], 1);
  posix_spawn_file_actions_adddup2(&actions, fd[1], 2);
  posix_spawn_file_actions_addclose(&actions, fd[0]);
  posix_spawn_file_actions_addclose(&actions, fd[1]);
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(fd[1]);
  std::string out;
  if (rc == 0) {
    char buffer[4096];
    for (ssize_t n; (n = read(fd[0], buffer, sizeof buffer)) != 0;)
      if (n > 0)
        out.append(buffer, static_cast<std::size_t>(n));
      else if (errno != EINTR)
        break;
  }
  close(fd[0]);
  if (rc != 0) return {-1, std::strerror(rc)};
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

// sbatch with `options`; returns the job id it printed (--parsable: a line "ID" or
// "ID;CLUSTER", beside any warnings).
std::string sbatch(const std::vector<std::string>& options) {
  std::vector<std::string> args = {"sbatch", "--parsable"};
  args.insert(args.end(), options.begin(), options.end());
  const auto [code, out] = run_program(args);
  if (code == -1)
    throw InputError("--slurm: cannot start sbatch (" + out +
                     "); is this a Slurm login node with sbatch on PATH?");
  std::string id;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    line = line.substr(0, line.find(';'));
    if (!line.empty() && line.find_first_not_of("0123456789") == std::string::npos) id = line;
  }
  if (code != 0 || id.empty())
    throw std::runtime_error("--slurm: sbatch failed (exit code " + std::to_string(code) +
                             "): " + out.substr(0, 1000));
  return id;
}

// Where the ids of the jobs last submitted from `script` are kept.
std::string ids_file(const std::string& script) {
  return script + ".jobs";
}

// "1-3,5,7-9" for the indices 1, 2, 3, 5, 7, 8, 9.
std::string index_ranges(const std::vector<int>& tasks) {
  std::string ranges;
  for (std::size_t i = 0; i < tasks.size();) {
    std::size_t j = i;
    while (j + 1 < tasks.size() && tasks[j + 1] == tasks[j] + 1) ++j;
    ranges += (ranges.empty() ? "" : ",") + std::to_string(tasks[i]) +
              (j > i ? "-" + std::to_string(tasks[j]) : "");
    i = j + 1;
  }
  return ranges;
}

}  // namespace

std::string shell_quoted(const std::string& word) {
  std::string q = "'";
  for (char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string pdsim_command(const std::string& command, const std::string& deck,
                          const std::string& output, const std::string& sbatch,
                          const std::string& tail) {
  return "pdsim " + command + " " + shell_quoted(deck) + " -o " + shell_quoted(output) +
         (sbatch.empty() ? "" : " --sbatch " + shell_quoted(sbatch)) + tail;
}

std::string this_executable() {
  return fs::read_symlink("/proc/self/exe").string();
}

std::string submitted(const SlurmArray& job, const SlurmJobs& ids, std::size_t total,
                      const std::string& pieces, const std::string& result,
                      const std::string& again) {
  std::ostringstream s;
  s << job.tasks.size() << " of " << total << " " << pieces << " submitted to Slurm as job array "
    << ids.array << " (" << job.threads << " thread" << (job.threads > 1 ? "s" : "") << " and "
    << std::ceil(job.memory_mib) << " MiB each"
    << (job.at_once > 0 ? ", " + std::to_string(job.at_once) + " at a time" : "") << ")\n"
    << "job " << ids.collect << " writes " << result << " once the array has ended\n"
    << "watch: squeue -j " << ids.array << "," << ids.collect << "\n"
    << "continue after a cancel or time limit: " << again;
  return s.str();
}

std::vector<int> pieces_to_submit(const std::vector<std::string>& files,
                                  const std::vector<bool>& finished, bool resume, bool force,
                                  std::vector<int>& running) {
  std::vector<int> submit;
  std::error_code ignored;
  for (std::size_t k = 0; k < files.size(); ++k) {
    const std::string& file = files[k];
    if (finished[k]) continue;
    if (output_locked(file)) {
      if (!resume)
        throw InputError(file +
                         ": is being run (its lock is held); wait for it, or cancel it and "
                         "submit with --resume");
      running.push_back(static_cast<int>(k + 1));
      continue;
    }
    if (!resume && !force && (fs::exists(file, ignored) || fs::exists(file + ".partial", ignored)))
      throw InputError(file +
                       ": left by an earlier run (its file or checkpoint); use --resume to keep "
                       "and continue it, or --force to run it anew");
    submit.push_back(static_cast<int>(k + 1));
  }
  if (force)
    for (int k : submit) {
      fs::remove(files[static_cast<std::size_t>(k - 1)], ignored);
      fs::remove(files[static_cast<std::size_t>(k - 1)] + ".partial", ignored);
    }
  return submit;
}

void refuse_if_queued(const std::string& script) {
  std::ifstream in(ids_file(script));
  std::string array;
  if (!(in >> array)) return;
  // squeue names a job it still holds; one that has left the queue is unknown (exit 1) or
  // listed by nobody.
  const auto [code, out] = run_program({"squeue", "--noheader", "--jobs=" + array, "--format=%i"});
  if (code == 0 && out.find_first_of("0123456789") != std::string::npos)
    throw InputError(script + ": its job array " + array + " is still in the queue (squeue -j " +
                     array + "); wait for it to end, or scancel it, before submitting again");
}

// A path for sbatch's --output, where % starts a pattern: each % doubled.
std::string literal(const std::string& path) {
  std::string out;
  for (char c : path) out += c == '%' ? std::string("%%") : std::string(1, c);
  return out;
}

SlurmJobs submit_array(const SlurmArray& job) {
  const std::string here = fs::current_path().string();
  const fs::path log = fs::path(here) / job.log;  // its file name holds the %a pattern
  std::vector<std::string> array = {
      "--job-name=" + job.name,
      "--chdir=" + here,
      "--array=" + index_ranges(job.tasks) +
          (job.at_once > 0 ? "%" + std::to_string(job.at_once) : ""),
      "--cpus-per-task=" + std::to_string(job.threads),
      "--mem=" + std::to_string(static_cast<long>(std::ceil(job.memory_mib))) + "M",
      "--requeue",
      "--output=" + literal(log.parent_path().string()) + "/" + log.filename().string()};
  array.insert(array.end(), job.options.begin(), job.options.end());  // the user's options win
  std::string command = "sbatch";
  for (const auto& a : array) command += " " + shell_quoted(a);
  command += " " + shell_quoted(job.script);
  for (std::size_t at = 0; (at = command.find('\n', at)) != std::string::npos; at += 3)
    command.replace(at, 1, "\n# ");  // a path's newline stays in the comment
  {
    std::ofstream out(job.script + ".partial");
    out << "#!/bin/bash\n# Submitted by pdsim as\n# " << command << "\nset -eu\n" << job.body;
    out.close();
    if (!out) throw SimulationError(job.script + ": could not be written");
    fs::rename(job.script + ".partial", job.script);
  }
  array.push_back(job.script);
  SlurmJobs ids;
  ids.array = sbatch(array);
  std::vector<std::string> collect = {
      "--job-name=" + job.name + "-collect", "--chdir=" + here,
      "--dependency=afterany:" + ids.array, "--cpus-per-task=1",
      "--output=" + literal((fs::path(here) / job.collect_log).string())};
  collect.insert(collect.end(), job.options.begin(), job.options.end());
  collect.push_back("--wrap=" + job.collect);
  std::ofstream(ids_file(job.script)) << ids.array << "\n";
  try {
    ids.collect = sbatch(collect);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string(e.what()) + "\n(job array " + ids.array +
                             " was submitted; the job after it was not: run `" + job.collect +
                             "` once the array has ended)");
  }
  return ids;
}

}  // namespace pdsim
