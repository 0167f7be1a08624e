#pragma once
/// @file
/// Statistics of any thread of this process as the kernel keeps them, for non-RT readers.
///
/// Linux: /proc/self/task/<tid>/stat and status (the same files `ps` and `top` read).
/// Cobalt: cobalt_thread_stat() adds primary-mode time and mode switches.

#include <cstdint>
#include <string>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread.hpp"

namespace vigil::platform {

/// One reading of a thread's kernel counters. Counters are cumulative since the thread started.
struct ThreadStats {
  int tid = 0;
  std::string name;  ///< comm, as in /proc/<pid>/task/<tid>/comm
  SchedPolicy policy = SchedPolicy::Other;
  bool policy_known = true;              ///< false for policies vigil does not model (RR, BATCH...)
  int priority = 0;                      ///< rt_priority (1..99 for FIFO, 0 otherwise)
  int last_cpu = -1;                     ///< CPU the thread last ran on
  std::uint64_t voluntary_switches = 0;  ///< voluntary_ctxt_switches: the thread blocked
  std::uint64_t involuntary_switches = 0;  ///< nonvoluntary_ctxt_switches: it was preempted
  std::uint64_t minor_faults = 0;
  std::uint64_t major_faults = 0;
  Nanos user_time_ns = 0;    ///< utime, with the kernel's tick resolution (USER_HZ)
  Nanos system_time_ns = 0;  ///< stime, likewise
  /// Cobalt only (0 on Linux): time in primary mode, and switches to secondary mode.
  Nanos primary_time_ns = 0;
  std::uint64_t mode_switches = 0;
};

/// Reads the statistics of thread `tid` of this process.
/// Fails with ESRCH when the thread has exited. Not RT-safe (file I/O, ~6 us); call it from a
/// supervisor or monitor thread, never from the thread being observed if that one is real-time.
[[nodiscard]] expected<ThreadStats, Error> read_thread_stats(int tid);

}  // namespace vigil::platform
