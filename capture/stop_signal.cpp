#include "capture/stop_signal.h"

#include <signal.h>

namespace rangebayes {
namespace {

std::atomic<bool> g_stop{false};
std::atomic<int> g_interrupts{0};

extern "C" void OnStopSignal(int signal_number) {
  g_stop.store(true, std::memory_order_relaxed);
  if (signal_number == SIGINT && g_interrupts.fetch_add(1) >= 1) {
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    sigaction(SIGINT, &dfl, nullptr);
  }
}

}  // namespace

void InstallStopSignalHandlers() {
  static_assert(std::atomic<bool>::is_always_lock_free, "the stop flag is written from a signal handler");
  struct sigaction action {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

std::atomic<bool>& StopFlag() { return g_stop; }

}  // namespace rangebayes
