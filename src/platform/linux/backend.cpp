// Linux backend of the shared POSIX part (src/platform/posix/backend.hpp): glibc throughout.
#include "platform/posix/backend.hpp"

#include "vigil/platform/process.hpp"

#include <sys/syscall.h>
#include <unistd.h>

namespace vigil::platform::detail {

const ThreadOps& thread_ops(const ThreadConfig& /*config*/) noexcept { return glibc_thread_ops(); }

int query_current_tid() noexcept { return static_cast<int>(::syscall(SYS_gettid)); }

int current_sched_param(int* policy, sched_param* param) noexcept {
  return pthread_getschedparam(pthread_self(), policy, param);
}

bool memory_always_locked() noexcept { return false; }

}  // namespace vigil::platform::detail

namespace vigil::platform {

// No real-time core to start on Linux: Thread::spawn, the clock and the waits are glibc's.
expected<void, Error> initialize() noexcept { return {}; }
expected<void, Error> initialize(int& /*argc*/, char**& /*argv*/) noexcept { return {}; }
bool initialized() noexcept { return true; }

}  // namespace vigil::platform
