#pragma once
// Private to the exec module: how every activity creates its thread.
#include <functional>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/thread.hpp"

namespace vigil::exec::detail {

/// Spawns an activity's thread with `config`. When SCHED_FIFO is refused (EPERM) and
/// `fallback_to_other` is set, spawns it SCHED_OTHER instead, sets `realtime_refused` and changes
/// `config` to what the thread got: never a silent downgrade. Not RT-safe.
inline expected<platform::Thread, Error> spawn_activity_thread(platform::ThreadConfig& config,
                                                               bool fallback_to_other,
                                                               const std::function<void()>& body,
                                                               bool& realtime_refused) {
  realtime_refused = false;
  auto t = platform::Thread::spawn(config, body);
  if (!t && config.policy == platform::SchedPolicy::Fifo && t.error().code == EPERM &&
      fallback_to_other) {
    realtime_refused = true;
    config.policy = platform::SchedPolicy::Other;
    config.priority = 0;
    t = platform::Thread::spawn(config, body);
  }
  return t;
}

}  // namespace vigil::exec::detail
