// Linux thread statistics from /proc/self/task/<tid>/stat and status (proc_pid_stat(5)).
#include "vigil/platform/thread_stats.hpp"

#include "platform/posix/proc_thread_stats.hpp"

namespace vigil::platform {

// The parser is shared with the Cobalt implementation (src/platform/posix/proc_thread_stats.hpp).
expected<ThreadStats, Error> read_thread_stats(int tid) {
  return detail::read_proc_thread_stats(tid);
}

}  // namespace vigil::platform
