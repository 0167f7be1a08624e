#pragma once
// Private to the platform module (never installed): reading a thread's Linux-side counters from
// /proc/self/task/<tid>/stat and status (proc_pid_stat(5)). Shared by the Linux implementation
// and the Cobalt one, which adds the Cobalt core's counters on top (src/platform/cobalt/).
//
// Header-only so that both implementations compile it into their own translation unit. It
// includes no Xenomai header: in a Cobalt build it is seen through libcobalt's wrapper headers
// like every other system header, which changes nothing here (ifstream I/O goes through
// libstdc++, outside the --wrap'ed objects). Not RT-safe (file I/O, allocation).

#include <fmt/format.h>
#include <sched.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/thread_stats.hpp"

namespace vigil::platform::detail {

inline expected<std::string, Error> slurp_proc_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    const int err = errno != 0 ? errno : ESRCH;
    return unexpected(Error{err, fmt::format("{}: {}", path, std::strerror(err))});
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline std::uint64_t proc_field_u64(std::string_view s) {
  std::uint64_t v = 0;
  std::from_chars(s.data(), s.data() + s.size(), v);
  return v;
}

/// The Linux kernel's view of thread `tid` of this process. Fails with ESRCH when the thread has
/// exited, EIO when a file does not have the expected format.
inline expected<ThreadStats, Error> read_proc_thread_stats(int tid) {
  const std::string dir = fmt::format("/proc/self/task/{}/", tid);
  auto stat = slurp_proc_file(dir + "stat");
  if (!stat) return unexpected(stat.error());
  auto status = slurp_proc_file(dir + "status");
  if (!status) return unexpected(status.error());

  ThreadStats st;
  st.tid = tid;
  // "pid (comm) state ppid ...": comm may hold spaces and parentheses, so split at the last ')'.
  const std::string& s = *stat;
  const auto open = s.find('(');
  const auto close = s.rfind(')');
  if (open == std::string::npos || close == std::string::npos || close < open) {
    return unexpected(Error{EIO, fmt::format("{}stat: unexpected format", dir)});
  }
  st.name = s.substr(open + 1, close - open - 1);
  // Fields after ')' start with field 3 (state); collect them by index.
  std::string_view rest(s.data() + close + 2, s.size() - close - 2);
  std::string_view fields[64];
  int n = 3;
  while (!rest.empty() && n < 64) {
    const auto sp = rest.find(' ');
    fields[n++] = rest.substr(0, sp);
    if (sp == std::string_view::npos) break;
    rest.remove_prefix(sp + 1);
  }
  if (n <= 41) return unexpected(Error{EIO, fmt::format("{}stat: only {} fields", dir, n - 1)});
  const long tick = sysconf(_SC_CLK_TCK);
  const Nanos ns_per_tick = kNanosPerSecond / (tick > 0 ? tick : 100);
  st.minor_faults = proc_field_u64(fields[10]);
  st.major_faults = proc_field_u64(fields[12]);
  st.user_time_ns = static_cast<Nanos>(proc_field_u64(fields[14])) * ns_per_tick;
  st.system_time_ns = static_cast<Nanos>(proc_field_u64(fields[15])) * ns_per_tick;
  st.last_cpu = static_cast<int>(proc_field_u64(fields[39]));
  st.priority = static_cast<int>(proc_field_u64(fields[40]));
  const auto policy = static_cast<int>(proc_field_u64(fields[41]));
  st.policy = policy == SCHED_FIFO ? SchedPolicy::Fifo : SchedPolicy::Other;
  st.policy_known = policy == SCHED_FIFO || policy == SCHED_OTHER;

  std::istringstream lines(*status);
  std::string line;
  while (std::getline(lines, line)) {
    constexpr std::string_view kVol = "voluntary_ctxt_switches:";
    constexpr std::string_view kInvol = "nonvoluntary_ctxt_switches:";
    std::string_view l(line);
    if (l.starts_with(kVol)) {
      l.remove_prefix(kVol.size());
      st.voluntary_switches = proc_field_u64(l.substr(l.find_first_not_of(" \t")));
    } else if (l.starts_with(kInvol)) {
      l.remove_prefix(kInvol.size());
      st.involuntary_switches = proc_field_u64(l.substr(l.find_first_not_of(" \t")));
    }
  }
  return st;
}

}  // namespace vigil::platform::detail
