// SIGINT or SIGTERM during a run: every run stops at its next step and keeps its finished
// frequencies. SIGTERM is what a scheduler sends at a time limit, preemption or scancel
// (Slurm: SIGTERM, then SIGKILL after KillWait), so it must leave a checkpoint too.
#pragma once

#include <csignal>

namespace pdsim {

// Set by SIGINT or SIGTERM while an InterruptScope is alive.
extern volatile std::sig_atomic_t g_interrupted;

// SIGINT and SIGTERM handled from the start of a run (a sweep's point may get one while it
// sets up) until its end.
struct InterruptScope {
  void (*previous_int)(int);
  void (*previous_term)(int);
  InterruptScope();
  ~InterruptScope();
};

}  // namespace pdsim
