// sim/cmd/store_sink.cc — see sim/cmd/store_sink.h.
#include "sim/cmd/store_sink.h"

#include <fmt/format.h>
#include <unistd.h>

namespace ncosim::sim {

std::atomic<int> g_stop{0};
static_assert(std::atomic<int>::is_always_lock_free,
              "the stop flag is written from a signal handler");

namespace {

extern "C" void on_stop_signal(int sig) {
  g_stop.store(sig);
  static const char msg[] =
      "\nncosim: stopping: no new run starts; the runs in progress finish and are committed "
      "(a second signal aborts at once)\n";
  const ssize_t ignored = ::write(2, msg, sizeof msg - 1);
  (void)ignored;
}

// Embedded (an interpreter's process, python/): a second signal must not end the interpreter.
extern "C" void on_stop_signal_embedded(int sig) {
  const bool first = g_stop.exchange(sig) == 0;
  static const char msg[] =
      "\nncosim: stopping: no new run starts; the runs in progress finish and are committed\n";
  if (!first) return;
  const ssize_t ignored = ::write(2, msg, sizeof msg - 1);
  (void)ignored;
}

}  // namespace

StopSignals::StopSignals(bool second_aborts) {
  g_stop.store(0);
  struct sigaction sa {};
  sa.sa_handler = second_aborts ? on_stop_signal : on_stop_signal_embedded;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = second_aborts ? SA_RESETHAND : 0;
  sigaction(SIGINT, &sa, &old_int_);
  sigaction(SIGTERM, &sa, &old_term_);
}
StopSignals::~StopSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

std::string signal_name(int sig) {
  if (sig == SIGINT) return "SIGINT";
  if (sig == SIGTERM) return "SIGTERM";
  return fmt::format("signal {}", sig);
}

}  // namespace ncosim::sim
