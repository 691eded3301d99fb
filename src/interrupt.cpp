#include "src/interrupt.hpp"

#include "src/frequency_run.hpp"

namespace pdsim {

volatile std::sig_atomic_t g_interrupted = 0;

namespace {
extern "C" void on_interrupt(int) {
  g_interrupted = 1;
  g_stop_runs = true;
}
}  // namespace

InterruptScope::InterruptScope()
    : previous_int(std::signal(SIGINT, on_interrupt)),
      previous_term(std::signal(SIGTERM, on_interrupt)) {}
InterruptScope::~InterruptScope() {
  std::signal(SIGINT, previous_int);
  std::signal(SIGTERM, previous_term);
}

}  // namespace pdsim
