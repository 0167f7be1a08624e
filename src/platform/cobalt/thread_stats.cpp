// Cobalt thread statistics: the Linux view from /proc (shared with the Linux implementation)
// plus the Cobalt core's view from cobalt_thread_stat().
//
// Linux's counters (utime, faults, context switches) only see the thread's secondary-mode life;
// what it did in primary mode is in the Cobalt core: xtime (CPU time in primary mode, ns), msw
// (relaxes to secondary mode, counted with or without PTHREAD_WARNSW when the kernel has
// CONFIG_XENO_OPT_STATS, else 0), cpu. cobalt_thread_stat() is a "current"-mode Cobalt system call
// that takes any TID, so a supervisor thread (Cobalt or not) can sample any thread
// (kernel/cobalt/posix/thread.c, thread_getstat; XENOMAI.md §2.1).
#include "vigil/platform/thread_stats.hpp"

#include "platform/cobalt/build_check.hpp"
#include "platform/posix/proc_thread_stats.hpp"

// Xenomai headers last: they define macros C++ headers must not see.
#include <cobalt/sys/cobalt.h>

namespace vigil::platform {

expected<ThreadStats, Error> read_thread_stats(int tid) {
  auto st = detail::read_proc_thread_stats(tid);
  if (!st) return st;
  cobalt_threadstat cs{};
  // 0, or a negative error number (unlike pthread_*): -ESRCH for a thread the Cobalt core does
  // not know (a plain Linux thread, or one that exited since /proc was read). Such a thread has
  // no primary-mode life, so the Cobalt fields stay 0 and the Linux figures are the answer.
  if (cobalt_thread_stat(static_cast<pid_t>(tid), &cs) == 0) {
    st->primary_time_ns = static_cast<Nanos>(cs.xtime);
    st->mode_switches = cs.msw;
    // Linux's "last CPU" is stale while the thread runs in primary mode; the core's is current.
    st->last_cpu = cs.cpu;
  }
  return st;
}

}  // namespace vigil::platform
