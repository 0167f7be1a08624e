// Linux backend of the shared POSIX part (src/platform/posix/backend.hpp): glibc throughout.
#include "platform/posix/backend.hpp"

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
