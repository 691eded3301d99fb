// SIGINT during a run: every run stops at its next step and keeps its finished frequencies.
#pragma once

#include <csignal>

namespace pdsim {

// Set by SIGINT while an InterruptScope is alive.
extern volatile std::sig_atomic_t g_interrupted;

// SIGINT handled from the start of a run (a sweep's point may get it while it sets up) until
// its end.
struct InterruptScope {
  void (*previous)(int);
  InterruptScope();
  ~InterruptScope();
};

}  // namespace pdsim
