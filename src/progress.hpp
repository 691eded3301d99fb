// The progress line of a run on stderr.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <string>
#include <vector>

namespace pdsim {

using Clock = std::chrono::steady_clock;

// Progress on stderr: a rewritten line on a terminal, a line every few seconds otherwise. Each
// task reports how many of its frequencies it has done (with the fraction of the current one),
// or frequency 0 while its bed settles. The ETA is the remaining work at the rate of the work
// done since the beds settled (how long a bed takes to come to rest is not known in advance).
// A steady-state frequency's fraction is its periods over max_periods, an upper bound that most
// frequencies stop far below, so there only whole frequencies count towards the rate, unless
// the driver models the work (set_work()): then work is simulated time, what finished points
// took and what each task's running point has run so far against what the points still planned
// are expected to take. Where points ahead are predicted nearer resonance than any finished one
// (the model extrapolates: the Saeki example's first minute said 298-415 s of a 1770 s run),
// the ETA says "or more": a range to every fill at the period cap there said 12,000-25,000 s,
// true but of no use.
class Progress {
 public:
  Progress(bool quiet, std::size_t tasks, double total, bool whole)
      : quiet_(quiet),
        tty_(isatty(fileno(stderr)) != 0),
        whole_(whole),
        done_(tasks, 0.0),
        running_(tasks, 0.0),
        total_(total) {}
  // `running_s`: the simulated time (s) the task's running point has run, where work is modelled.
  void update(std::size_t task, double done, double frequency, double running_s = 0) {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = Clock::now();
    if (frequency > 0) {
      done_[task] = done;
      running_[task] = running_s;
      if (!working_) working_ = true, work_start_ = now;
    }
    if (now - last_ < (tty_ ? std::chrono::milliseconds(250) : std::chrono::seconds(5))) return;
    last_ = now;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const char* end = tty_ ? "   " : "\n";
    if (frequency <= 0) {
      std::fprintf(stderr, "%ssettling the bed  elapsed %.0f s%s", tty_ ? "\r" : "", elapsed, end);
    } else {
      double sum = 0, counted = 0, left = total_;
      for (double d : done_) sum += d, counted += whole_ ? std::floor(d) : d;
      if (finished_s_ >= 0) {  // modelled: simulated seconds
        double running = 0;
        for (double r : running_) running += r;
        sum = counted = finished_s_ + running;
        left = sum + std::max(0.0, remaining_s_ - running);
      }
      const double working = std::chrono::duration<double>(now - work_start_).count();
      std::fprintf(stderr, "%sf = %.3f Hz  %5.1f%%  elapsed %.0f s  ", tty_ ? "\r" : "", frequency,
                   100 * std::min(1.0, sum / left), elapsed);
      if (counted > 0) {
        std::fprintf(stderr, "ETA %.0f s%s%s", working * std::max(0.0, left - counted) / counted,
                     beyond_ ? " or more (nearer resonance ahead)" : "", end);
      } else {
        std::fprintf(stderr, "ETA after the first %s%s", whole_ ? "frequency" : "steps", end);
      }
    }
    std::fflush(stderr);
  }
  // The driver's model of the work, simulated seconds: what finished points took, and what
  // the points still planned (the running ones whole) are expected to take.
  // `beyond`: points ahead are predicted nearer resonance than any finished one.
  void set_work(double finished_s, double remaining_s, bool beyond) {
    std::lock_guard<std::mutex> lock(mutex_);
    finished_s_ = finished_s;
    remaining_s_ = remaining_s;
    beyond_ = beyond;
  }
  // More work than planned: fills sent to a point that wants them.
  void add_total(double more) {
    std::lock_guard<std::mutex> lock(mutex_);
    total_ += more;
  }
  // A line of its own (a finished frequency), not overwritten by the progress line.
  void say(const std::string& line) {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    std::fprintf(stderr, "%s%s\n", tty_ ? "\r\033[K" : "", line.c_str());
    std::fflush(stderr);
  }
  void finish() {
    if (!quiet_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  bool quiet_, tty_, whole_, working_ = false;
  std::mutex mutex_;
  std::vector<double> done_, running_;
  double total_, finished_s_ = -1, remaining_s_ = 0;
  bool beyond_ = false;
  Clock::time_point start_ = Clock::now(), last_{}, work_start_{};
};

}  // namespace pdsim
