#include "src/sweep.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <optional>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <iostream>
#include <thread>
#include <vector>

#include "io/excitation.hpp"
#include "io/results.hpp"
#include "src/format.hpp"
#include "src/interrupt.hpp"
#include "src/run.hpp"
#include "src/scene.hpp"
#include "src/slurm.hpp"

extern char** environ;

namespace pdsim {
namespace {

namespace fs = std::filesystem;

struct Point {
  int index = 0;
  Deck deck;
  std::string file, log;
  bool resume = false;  // continue from the point's checkpoint
  bool kept = false;    // finished by an earlier sweep
  pid_t pid = 0;
  int code = -1;       // exit code of its process (kRunning: another process is running it)
  std::string detail;  // why it failed, or how far an interrupted one came
};
constexpr int kRunning = -2;

std::string last_line(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

// Why a point's process failed: its "error:" or "simulation failed:" line (the last line is
// often only where its particles were dumped), else its last line.
std::string cause(const std::string& path) {
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("error: ", 0) == 0 || line.rfind("simulation failed: ", 0) == 0)
      return line.substr(0, 400);
  return last_line(path);
}

std::string csv(const std::string& field) {
  if (field.find_first_of(",\"\n") == std::string::npos) return field;
  std::string quoted = "\"";
  for (char c : field) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// The environment variable that tells a point process which sweep started it.
constexpr const char* kParent = "PDSIM_SWEEP_PARENT";

pid_t launch(const Point& p, const SweepOptions& o, int threads) {
  std::vector<std::string> args = {"pdsim",
                                   "run",
                                   p.deck.path,
                                   "--point",
                                   std::to_string(p.index),
                                   "--output",
                                   p.file,
                                   "--threads",
                                   std::to_string(threads),
                                   "--quiet"};
  if (o.force) args.push_back("--force");
  if (p.resume) args.push_back("--resume");
  if (o.backend) args.insert(args.end(), {"--backend", backend_name(*o.backend)});
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, p.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<char*> env;
  for (char** e = environ; *e != nullptr; ++e)
    if (std::strncmp(*e, kParent, std::strlen(kParent)) != 0) env.push_back(*e);
  std::string parent = std::string(kParent) + "=" + std::to_string(getpid());
  env.push_back(parent.data());
  env.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, argv.data(), env.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0)
    throw SimulationError(std::string("cannot start the process of a sweep point: ") +
                          std::strerror(rc));
  return pid;
}

// One row per point: its values, how it ended, and the headline results of its file.
void write_summary(const Deck& deck, const std::vector<Point>& points, const std::string& path) {
  const bool frf = sweeps_frf(deck.excitation);
  const bool prescribed = traits(deck.excitation.kind).moves_containers;
  std::ofstream out(path + ".partial");
  out << "point";
  for (const auto& key : deck.sweep.keys) out << "," << csv(key);
  out << ",status,file,wall_time_s,particle_steps_per_s";
  if (frf)
    out << ",peak_amplitude_m,peak_frequency_hz,results,higher_unresolved_amplitude_m,"
           "higher_unresolved_frequency_hz";
  if (prescribed) out << ",peak_power_w,peak_power_frequency_hz";
  out << "\n";
  for (const Point& p : points) {
    out << p.index;
    const auto choice = deck.sweep.choice(p.index);
    for (std::size_t k = 0; k < choice.size(); ++k)
      out << "," << csv(deck.sweep.values[k][choice[k]]);
    const bool finished = p.kept || p.code == 0;
    out << ","
        << (finished             ? "finished"
            : p.code == 130      ? "interrupted"
            : p.code == kRunning ? "running"
            : p.code < 0         ? "not run"
                                 : "failed");
    out << "," << csv(fs::path(p.file).filename().string());
    if (!finished) {
      out << "\n";
      continue;
    }
    Results r;
    try {
      r = read_results(p.file);
    } catch (const std::exception& e) {
      out << ",unreadable: " << csv(e.what()) << "\n";
      continue;
    }
    const double wall = r.meta_numbers.at("wall_time_s");
    out << "," << number(wall, 6) << "," << number(r.meta_numbers.at("particle_steps") / wall, 6);
    auto peak_of = [&](const std::vector<double>& v, const std::vector<double>& f) {
      const auto k = static_cast<std::size_t>(std::max_element(v.begin(), v.end()) - v.begin());
      out << "," << number(v[k], 6) << "," << number(f[k], 6);
    };
    if (frf && !r.frf.frequency.empty()) {
      // The run's own headline (frf_peak: over every result point), NaN without results.
      const FrfPeak peak = frf_peak(r.frf, r.fills);
      out << "," << number(peak.found ? peak.amplitude : std::nan(""), 6) << ","
          << number(peak.found ? peak.frequency : std::nan(""), 6);
      int converged = 0;
      for (int c : r.frf.converged) converged += c;
      out << "," << converged << "/" << r.frf.converged.size();
      // The hard part beside the headline: the highest mean where not a result, if higher.
      out << "," << number(peak.higher ? peak.higher_amplitude : std::nan(""), 6) << ","
          << number(peak.higher ? peak.higher_frequency : std::nan(""), 6);
    }
    if (prescribed && !r.prescribed.frequency.empty())
      peak_of(r.prescribed.dissipated_power, r.prescribed.frequency);
    out << "\n";
  }
  out.close();
  if (!out) throw SimulationError(path + ".partial: could not be written");
  fs::rename(path + ".partial", path);
}

// Point k of the sweep in `folder`: its deck, file and log.
Point sweep_point_at(const Deck& deck, const std::string& folder, int k, Deck point_deck) {
  Point p;
  p.index = k;
  p.deck = std::move(point_deck);
  p.file = (fs::path(folder) / point_file(deck, k)).string();
  p.log = p.file.substr(0, p.file.size() - 3) + ".log";
  return p;
}

// What a point's files say of it: finished (its file, of this point's deck), running (its
// output's lock held), interrupted (a checkpoint, or a log without an error), failed (an error
// in its log), or not run (nothing).
void read_state(Point& p) {
  std::error_code ignored;
  if (fs::exists(p.file, ignored)) {
    const std::string changed = changes_since(read_results(p.file), p.deck);
    p.kept = changed.empty();
    if (!p.kept)
      p.code = 2, p.detail = "its file was run from another deck or point (" + changed + ")";
    return;
  }
  if (output_locked(p.file)) {
    p.code = kRunning;
    return;
  }
  const std::string why = fs::exists(p.log, ignored) ? cause(p.log) : "";
  const bool error = why.rfind("error: ", 0) == 0 || why.rfind("simulation failed: ", 0) == 0;
  if (error && why.find("interrupted") == std::string::npos) {
    p.code = 2, p.detail = why + " [" + p.log + "]";
  } else if (fs::exists(p.file + ".partial", ignored)) {
    p.code = 130, p.detail = "finished frequencies kept in " + p.file + ".partial";
  } else if (fs::exists(p.log, ignored)) {
    p.code = 130, p.detail = "stopped before its first frequency [" + p.log + "]";
  }
}

// --status and --collect: the sweep's files read, nothing run.
int read_sweep(const Deck& deck, const SweepOptions& o, const std::string& folder) {
  const int count = deck.sweep.points();
  std::vector<Point> points(static_cast<std::size_t>(count));
  int finished = 0;
  std::string missing;
  for (int k = 1; k <= count; ++k) {
    Point& p = points[static_cast<std::size_t>(k - 1)];
    p = sweep_point_at(deck, folder, k, sweep_point(deck, k));
    read_state(p);
    finished += p.kept;
    const std::string state = p.kept               ? "finished"
                              : p.code == kRunning ? "running"
                              : p.code == 130      ? "interrupted"
                              : p.code == 2        ? "failed"
                                                   : "not run";
    if (o.status || !p.kept)
      (o.status ? std::cout : std::cerr)
          << "point " << k << "/" << count << " (" << deck.sweep.describe(k) << "): " << state
          << (p.detail.empty() ? "" : ": " + p.detail) << "\n";
    if (!p.kept) missing += (missing.empty() ? "" : ", ") + std::to_string(k);
  }
  if (o.collect) {
    if (!fs::is_directory(folder)) throw InputError(folder + ": no such sweep folder");
    const std::string summary = (fs::path(folder) / "summary.csv").string();
    write_summary(deck, points, summary);
    std::cout << finished << " of " << count << " points finished; summary in " << summary
              << (missing.empty() ? "" : "; not finished: points " + missing) << "\n";
  } else {
    std::cout << finished << " of " << count << " points finished in " << folder << "/"
              << (missing.empty() ? "" : "; not finished: points " + missing) << "\n";
  }
  return finished == count ? 0 : 2;
}

// This process's rank and the number of ranks, from the launcher's environment.
std::pair<int, int> launcher_rank() {
  const std::pair<const char*, const char*> names[] = {
      {"OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"},
      {"PMI_RANK", "PMI_SIZE"},
      {"SLURM_PROCID", "SLURM_NTASKS"}};
  for (const auto& [rank_name, size_name] : names) {
    const char* rank = std::getenv(rank_name);
    const char* size = std::getenv(size_name);
    if (!rank || !size) continue;
    char* end = nullptr;
    const long r = std::strtol(rank, &end, 10);
    const bool rank_ok = *rank && !*end;
    const long n = std::strtol(size, &end, 10);
    if (!rank_ok || !*size || *end || n < 1 || r < 0 || r >= n)
      throw InputError(std::string("--ranks: ") + rank_name + " = '" + rank + "' and " + size_name +
                       " = '" + size + "' are not a rank below a size");
    return {static_cast<int>(r), static_cast<int>(n)};
  }
  throw InputError(
      "--ranks: no launcher rank in the environment (OMPI_COMM_WORLD_RANK/SIZE, PMI_RANK/SIZE "
      "or SLURM_PROCID/NTASKS); start it with mpirun -np N or srun -n N");
}

}  // namespace

std::string sweep_folder(const Deck& deck) {
  const fs::path base = deck.output.file.empty() ? fs::path(fs::path(deck.path).stem().string())
                                                 : fs::path(deck.output.file);
  return (base.parent_path() / (base.stem().string() + "_sweep")).string();
}

std::string point_file(const Deck& deck, int point) {
  const std::size_t digits = std::max<std::size_t>(3, std::to_string(deck.sweep.points()).size());
  std::string number = std::to_string(point);
  number.insert(0, digits - std::min(digits, number.size()), '0');
  return "p" + number + ".h5";
}

namespace {

// The deck of every point, each checked as `pdsim run` would check it; an error names its point.
// `memory_mib`, if given, gets the most memory a point needs on `threads` threads.
std::vector<Deck> checked_points(const Deck& deck, int threads, std::optional<Backend> backend,
                                 double* memory_mib = nullptr) {
  std::vector<Deck> points;
  for (int k = 1; k <= deck.sweep.points(); ++k) {
    points.push_back(sweep_point(deck, k));
    try {
      const Scene scene = build_scene(points.back(), threads, backend);
      if (memory_mib)
        *memory_mib =
            std::max(*memory_mib, memory_estimate_mib(plan_of(points.back(), scene), scene));
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + " (sweep point " + std::to_string(k) + ": " +
                       deck.sweep.describe(k) + ")");
    }
  }
  return points;
}

// --slurm: the points not finished, as one job array, and a collect job after it (run_sweep).
int submit_slurm(const Deck& deck, const SweepOptions& o, const std::string& folder,
                 const std::vector<Point>& points, int threads, double memory_mib) {
  SlurmArray job;
  job.script = (fs::path(folder) / "slurm_array.sh").string();
  refuse_if_queued(job.script);
  std::vector<std::string> files;
  std::vector<bool> finished;
  for (const Point& p : points) {
    files.push_back(p.file);
    finished.push_back(p.kept);
  }
  std::vector<int> running;
  job.tasks = pieces_to_submit(files, finished, o.resume, o.force, running);
  std::string busy;
  for (int k : running) busy += (busy.empty() ? "" : ", ") + std::to_string(k);
  if (!busy.empty()) std::printf("points %s are running and are not submitted\n", busy.c_str());
  if (job.tasks.empty()) {
    std::printf("nothing to submit: %d of %zu points finished; `%s` writes the summary\n",
                static_cast<int>(std::count(finished.begin(), finished.end(), true)), points.size(),
                pdsim_command("sweep", deck.path, folder, "", " --collect").c_str());
    return 0;
  }
  const std::string exe = shell_quoted(this_executable());
  const std::string files_in = fs::path(points.front().file).parent_path().string();
  const std::string digits = std::to_string(point_file(deck, 1).size() - 4);  // "p001.h5"
  job.name = "pdsim-" + fs::path(folder).filename().string();
  job.at_once = o.jobs;
  job.threads = threads;
  job.memory_mib = memory_mib;
  job.log = (fs::path(files_in) / ("p%" + digits + "a.log")).string();
  // Task K runs point K as the local sweep does: from its checkpoint when it has one
  // (requeued, resubmitted), not at all when its file is there.
  job.body =
      "point=$SLURM_ARRAY_TASK_ID\n"
      "file=$(printf '%s/p%0" +
      digits + "d.h5' " + shell_quoted(files_in) + " \"$point\")\n" +
      "if [ -e \"$file\" ]; then echo \"$file: finished earlier, kept\"; exit 0; fi\n"
      "resume=\n"
      "if [ -e \"$file.partial\" ]; then\n"
      "  resume=--resume\n"
      "  echo \"point $point: continuing from $file.partial\"\n"
      "fi\n"
      "exec " +
      exe + " run " + shell_quoted(deck.path) +
      " --point \"$point\" --output \"$file\" --threads " + std::to_string(threads) + " --quiet" +
      (o.backend ? std::string(" --backend ") + backend_name(*o.backend) : std::string()) +
      " $resume\n";
  job.collect = exe + " sweep " + shell_quoted(deck.path) + " --output " + shell_quoted(folder) +
                " --collect";
  job.collect_log = (fs::path(folder) / "collect.log").string();
  job.options = sbatch_options(deck.cluster.sbatch, "[cluster] sbatch");
  for (const auto& option : sbatch_options(o.sbatch, "--sbatch")) job.options.push_back(option);
  const SlurmJobs ids = submit_array(job);
  std::printf("sweep: %s\n",
              submitted(job, ids, points.size(), "points", folder + "/summary.csv",
                        pdsim_command("sweep", deck.path, folder, o.sbatch, " --slurm --resume"))
                  .c_str());
  std::printf("each point: %s\n",
              pdsim_command("sweep", deck.path, folder, "", " --status").c_str());
  return 0;
}

}  // namespace

std::string check_sweep(const Deck& deck, int threads, std::optional<Backend> backend) {
  std::ostringstream s;
  s << "sweep: " << deck.sweep.points() << " points, files in " << sweep_folder(deck) << "/\n";
  // What `pdsim sweep --slurm` would ask for each task: `threads` (--threads), else the deck's
  // solver.threads, else one.
  const int task_threads = threads > 0 ? threads : std::max(1, deck.solver.threads);
  double memory_mib = 0;
  checked_points(deck, task_threads, backend, &memory_mib);
  for (int k = 1; k <= deck.sweep.points(); ++k)
    s << "  point " << k << ": " << deck.sweep.describe(k) << "\n";
  s << "slurm (sweep --slurm): a task per point, " << task_threads << " thread"
    << (task_threads > 1 ? "s" : "") << " and " << std::ceil(memory_mib) << " MiB each";
  if (!deck.cluster.sbatch.empty()) s << ", with " << deck.cluster.sbatch;
  s << "\n";
  return s.str();
}

void follow_sweep() {
  const char* parent = std::getenv(kParent);
  if (parent == nullptr) return;
  prctl(PR_SET_PDEATHSIG, SIGINT);
  // The sweep may have died before the request: then the parent is already someone else.
  if (std::to_string(getppid()) != parent) {
    std::fprintf(stderr,
                 "simulation failed: interrupted: the sweep that started this point is "
                 "gone\n");
    std::exit(130);
  }
}

int run_sweep(const Deck& deck, const SweepOptions& o) {
  const int count = deck.sweep.points();
  if (count == 0)
    throw InputError(deck.path + ": the deck has no [sweep] table; run it with `pdsim run`");
  const std::string folder = o.folder.empty() ? sweep_folder(deck) : o.folder;
  if (o.slurm && (o.ranks || o.status || o.collect))
    throw InputError(std::string("--slurm and ") +
                     (o.ranks    ? "--ranks"
                      : o.status ? "--status"
                                 : "--collect") +
                     ": choose one (--slurm submits a job array)");
  if (o.status || o.collect) return read_sweep(deck, o, folder);
  if (!o.slurm && !o.sbatch.empty()) throw InputError("--sbatch: only with --slurm");
  sbatch_options(o.sbatch, "--sbatch");  // refused before anything is checked or written
  const auto [rank, ranks] = o.ranks ? launcher_rank() : std::pair{0, 1};
  auto mine = [rank = rank, ranks = ranks](int k) { return (k - 1) % ranks == rank; };
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int jobs = std::min(count, o.jobs > 0 ? o.jobs : cores);
  // A Slurm task is given the cores it asks for: one, unless the deck or --threads says more.
  const int threads = o.threads > 0             ? o.threads
                      : !o.slurm                ? std::max(1, cores / jobs)
                      : deck.solver.threads > 0 ? deck.solver.threads
                                                : 1;

  // Every point is checked before any runs, so that a bad value stops the sweep at once.
  double memory_mib = 0;
  std::vector<Deck> decks = checked_points(deck, threads, o.backend, &memory_mib);
  std::vector<Point> points(static_cast<std::size_t>(count));
  for (int k = 1; k <= count; ++k) {
    Point& p = points[static_cast<std::size_t>(k - 1)];
    p = sweep_point_at(deck, folder, k, std::move(decks[static_cast<std::size_t>(k - 1)]));
    if (!mine(k)) continue;  // another rank's
    if (fs::exists(p.file) && !o.force) {
      if (!o.resume)
        throw InputError(p.file +
                         ": exists; use --resume to keep finished points or --force to rerun them");
      if (const std::string changed = changes_since(read_results(p.file), p.deck); !changed.empty())
        throw InputError(p.file + ": was run from another deck or point (" + changed +
                         "); use --force to rerun it");
      p.kept = true;
    }
    p.resume = o.resume && !p.kept && fs::exists(p.file + ".partial");
  }
  fs::create_directories(folder);
  if (o.slurm) return submit_slurm(deck, o, folder, points, threads, memory_mib);
  std::printf("sweep: %d points, %d at a time, %d thread%s each, files in %s/\n", count, jobs,
              threads, threads > 1 ? "s" : "", folder.c_str());
  std::fflush(stdout);

  // Without SA_RESTART, so that a signal interrupts waitpid() and is passed on to the points.
  std::optional<InterruptScope> interrupts(std::in_place, false);
  std::size_t next = 0;
  int running = 0;
  bool forwarded = false;
  for (;;) {
    while (!interrupted() && running < jobs && next < points.size()) {
      Point& p = points[next++];
      if (!mine(p.index)) continue;
      if (p.kept) {
        std::printf("point %d/%d (%s): finished earlier, kept\n", p.index, count,
                    deck.sweep.describe(p.index).c_str());
        continue;
      }
      p.pid = launch(p, o, threads);
      ++running;
    }
    if (running == 0) break;
    if (interrupted() && !forwarded) {  // let every running point write its checkpoint
      for (const Point& p : points)
        if (p.pid > 0 && p.code < 0) kill(p.pid, SIGINT);
      forwarded = true;
    }
    // Polled, so that a signal arriving at any moment is passed on within 50 ms.
    int status = 0;
    const pid_t pid = waitpid(-1, &status, WNOHANG);
    if (pid == 0 || (pid < 0 && errno == EINTR)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      continue;
    }
    if (pid < 0) throw SimulationError("waitpid failed: " + std::string(strerror(errno)));
    auto found =
        std::find_if(points.begin(), points.end(), [&](const Point& p) { return p.pid == pid; });
    if (found == points.end()) continue;
    --running;
    Point& p = *found;
    p.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    const std::string outcome = p.code == 0     ? last_line(p.log)
                                : p.code == 130 ? (fs::exists(p.file + ".partial")
                                                       ? "interrupted; finished frequencies kept"
                                                       : "interrupted before its first frequency")
                                                : "failed (exit code " + std::to_string(p.code) +
                                                      "): " + cause(p.log) + " [" + p.log + "]";
    std::printf("point %d/%d (%s): %s\n", p.index, count, deck.sweep.describe(p.index).c_str(),
                outcome.c_str());
    std::fflush(stdout);
  }
  interrupts.reset();

  const std::string summary = (fs::path(folder) / "summary.csv").string();
  if (ranks > 1) {
    // The other ranks' points as their files say; the rank that finds all finished (the last
    // to finish) writes the summary, one rank at a time.
    int own = 0, done = 0;
    for (Point& p : points) {
      if (mine(p.index)) {
        own += 1, done += p.kept || p.code == 0;
      } else {
        read_state(p);
      }
    }
    int finished = 0;
    for (const Point& p : points) finished += p.kept || p.code == 0;
    std::printf("rank %d of %d: %d of its %d points finished\n", rank, ranks, done, own);
    if (finished == count) {
      // Two ranks finishing together both write it, one after the other (10 s at most).
      for (int attempt = 0;; ++attempt) try {
          const OutputLock lock(summary);
          write_summary(deck, points, summary);
          break;
        } catch (const std::runtime_error&) {
          if (attempt == 200) throw;
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
      std::printf("%d of %d points finished; summary in %s\n", finished, count, summary.c_str());
    }
    if (interrupted()) return 130;
    return done < own ? 2 : 0;
  }
  write_summary(deck, points, summary);
  int finished = 0;
  for (const Point& p : points) finished += p.kept || p.code == 0;
  std::printf("%d of %d points finished; summary in %s\n", finished, count, summary.c_str());
  if (interrupted()) {
    std::printf("interrupted: continue with `pdsim sweep %s --resume`\n", deck.path.c_str());
    return 130;
  }
  return finished < count ? 2 : 0;
}

}  // namespace pdsim
