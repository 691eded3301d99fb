// The process's one stop. SIGINT or SIGTERM during a run or a sweep: every run stops at its
// next step and keeps its finished frequencies; a sweep passes the signal on to its points.
// SIGTERM is what a scheduler sends at a time limit, preemption or scancel (Slurm: SIGTERM,
// then SIGKILL after KillWait), so it must leave a checkpoint too. Runs also stop, without a
// signal, when another fill fails or a --stop-after is reached (request_stop()).
#pragma once

#include <csignal>

namespace pdsim {

// Whether SIGINT or SIGTERM arrived while an InterruptScope was alive.
bool interrupted();

// Whether runs are to stop at their next step (a signal, or request_stop()); FrequencyRun
// polls it every step and throws Interrupted.
bool stop_requested();
void request_stop();
// Runs may go on again, unless a signal has arrived (a run starting after one stops at once).
void clear_stop();

// SIGINT and SIGTERM handled from the start of a run or sweep (a sweep's point may get one
// while it sets up) until its end. `restart`: calls a signal interrupts are restarted (a
// run); a sweep asks otherwise, so that its waitpid() returns and it passes the signal on.
class InterruptScope {
 public:
  explicit InterruptScope(bool restart = true);
  ~InterruptScope();
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;

 private:
  struct sigaction previous_int_ {
  }, previous_term_{};
};

}  // namespace pdsim
