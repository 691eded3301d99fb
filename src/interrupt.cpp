#include "src/interrupt.hpp"

#include <atomic>

namespace pdsim {

namespace {

volatile std::sig_atomic_t g_signal = 0;
std::atomic<bool> g_stop{false};  // lock-free, so the handler may set it
static_assert(std::atomic<bool>::is_always_lock_free, "a signal handler sets it");

extern "C" void on_interrupt(int) {
  g_signal = 1;
  g_stop = true;
}

}  // namespace

bool interrupted() {
  return g_signal != 0;
}
bool stop_requested() {
  return g_stop;
}
void request_stop() {
  g_stop = true;
}
void clear_stop() {
  g_stop = g_signal != 0;
}

InterruptScope::InterruptScope(bool restart) {
  struct sigaction stop = {};
  stop.sa_handler = on_interrupt;
  stop.sa_flags = restart ? SA_RESTART : 0;
  sigemptyset(&stop.sa_mask);
  sigaction(SIGINT, &stop, &previous_int_);
  sigaction(SIGTERM, &stop, &previous_term_);
}

InterruptScope::~InterruptScope() {
  sigaction(SIGINT, &previous_int_, nullptr);
  sigaction(SIGTERM, &previous_term_, nullptr);
}

}  // namespace pdsim
