// Platform-independent parts of the platform module: names, reports, per-thread counters.
#include "vigil/platform/memory.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/thread.hpp"

#include <string>

namespace vigil::platform::detail {
thread_local constinit std::uint64_t tls_allocations __attribute__((tls_model("initial-exec"))) = 0;
thread_local constinit std::uint64_t tls_mode_switches __attribute__((tls_model("initial-exec"))) =
    0;
bool alloc_guard_linked = false;
}  // namespace vigil::platform::detail

namespace vigil::platform {

const char* to_string(SchedPolicy p) noexcept {
  switch (p) {
    case SchedPolicy::Fifo:
      return "FIFO";
    case SchedPolicy::Other:
      return "OTHER";
  }
  return "?";
}

const char* to_string(LossCause c) noexcept {
  switch (c) {
    case LossCause::Allocation:
      return "allocation";
    case LossCause::Blocking:
      return "blocking";
    case LossCause::MinorFault:
      return "minor_fault";
    case LossCause::MajorFault:
      return "major_fault";
    case LossCause::ModeSwitch:
      return "mode_switch";
  }
  return "?";
}

bool allocation_counting_available() noexcept { return detail::alloc_guard_linked; }

std::string RealtimeSetupReport::describe() const {
  std::string s;
  s += "memory locked: ";
  s += memory_locked ? "yes" : "no (errno " + std::to_string(lock_errno) + ")";
  s += "\nmalloc tuned: ";
  s += malloc_tuned ? "yes" : "no";
  s += "\nmalloc arenas: ";
  s += malloc_arena_max > 0 ? "at most " + std::to_string(malloc_arena_max) : "glibc default";
  s += "\nstack prefaulted: " + std::to_string(stack_prefaulted) + " bytes";
  s += "\nheap prefaulted: " + std::to_string(heap_prefaulted) + " bytes";
  s += "\nSCHED_FIFO allowed: ";
  s += can_use_fifo ? "yes" : "no";
  s += "\nzero CPU latency requested: ";
  s += cpu_latency_requested ? "yes" : "no";
  if (!core_error.empty()) s += "\nreal-time core not started: " + core_error;
  s += '\n';
  return s;
}

}  // namespace vigil::platform
