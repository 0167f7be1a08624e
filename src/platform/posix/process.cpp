// Linux process services: isatty and SIGINT/SIGTERM handling.
#include "vigil/platform/process.hpp"

#include <unistd.h>

#include <atomic>
#include <csignal>

namespace vigil::platform {

namespace {
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");
extern "C" void on_stop_signal(int /*sig*/) { g_stop.store(true, std::memory_order_relaxed); }
}  // namespace

bool is_terminal(std::FILE* stream) noexcept {
  return stream != nullptr && isatty(fileno(stream)) != 0;
}

void install_stop_signals() noexcept {
  struct sigaction sa {};
  sa.sa_handler = &on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool stop_requested() noexcept { return g_stop.load(std::memory_order_relaxed); }

}  // namespace vigil::platform
