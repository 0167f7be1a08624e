// Linux real-time-loss probes: getrusage(RUSAGE_THREAD); no mode switches on Linux.
#include "vigil/platform/rt_loss.hpp"

#include <sys/resource.h>

namespace vigil::platform {

ThreadUsage thread_usage() noexcept {
  rusage ru{};
  getrusage(RUSAGE_THREAD, &ru);
  ThreadUsage u;
  u.voluntary_switches = static_cast<std::uint64_t>(ru.ru_nvcsw);
  u.involuntary_switches = static_cast<std::uint64_t>(ru.ru_nivcsw);
  u.minor_faults = static_cast<std::uint64_t>(ru.ru_minflt);
  u.major_faults = static_cast<std::uint64_t>(ru.ru_majflt);
  return u;
}

bool arm_mode_switch_detection() noexcept { return false; }

// There is no SIGDEBUG on Linux: every reason stays 0.
ModeSwitchReasons mode_switch_reasons() noexcept { return {}; }

}  // namespace vigil::platform
