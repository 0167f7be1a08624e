// Process identity, death and exit status for non-parents (pidfd, /proc), and the exit recorder
// (on_exit + default-action signal handlers) a supervised process installs for itself.
#include "vigil/platform/process_watch.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string_view>
#include <utility>
#include <vector>

namespace vigil::platform {

namespace {

// Reads a small /proc file whole (they report size 0, so read until EOF).
std::string read_small_file(const char* path, std::size_t max = 8192) {
  std::string out;
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return out;
  char buf[1024];
  while (out.size() < max) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  if (out.size() > max) out.resize(max);
  return out;
}

// The fields of /proc/<pid>/stat after "(comm)": field 3 (state) is index 0.
struct StatFields {
  char state = '?';
  std::uint64_t start_ticks = 0;  // field 22
  int exit_code = -1;             // field 52 (Linux >= 3.5), -1 when absent
  bool ok = false;
};

StatFields parse_stat(const std::string& s) {
  StatFields f;
  // comm may contain spaces and parentheses: the fields start after the LAST ')'.
  const auto close = s.rfind(')');
  if (close == std::string::npos || close + 2 >= s.size()) return f;
  std::string_view rest(s);
  rest.remove_prefix(close + 2);
  int field = 3;
  while (!rest.empty()) {
    const auto sp = rest.find(' ');
    const std::string_view tok = rest.substr(0, sp);
    if (field == 3 && !tok.empty()) f.state = tok[0];
    if (field == 22) {
      f.start_ticks = std::strtoull(std::string(tok).c_str(), nullptr, 10);
      f.ok = true;
    }
    if (field == 52) f.exit_code = std::atoi(std::string(tok).c_str());
    if (sp == std::string_view::npos) break;
    rest.remove_prefix(sp + 1);
    ++field;
  }
  return f;
}

StatFields stat_of(std::int32_t pid) {
  char path[64];
  std::snprintf(path, sizeof path, "/proc/%d/stat", static_cast<int>(pid));
  return parse_stat(read_small_file(path));
}

// PIDFD_GET_INFO (Linux 6.13) with PIDFD_INFO_EXIT (6.15); the C library headers of older
// systems do not have them, so the first published layout (64 bytes) is spelt out here. The
// kernel accepts any size it knows and fills what it has.
struct PidfdInfo {
  std::uint64_t mask;
  std::uint64_t cgroupid;
  std::uint32_t pid, tgid, ppid, ruid, rgid, euid, egid, suid, sgid, fsuid, fsgid;
  std::int32_t exit_code;
};
static_assert(sizeof(PidfdInfo) == 64, "PIDFD_INFO_SIZE_VER0");
constexpr unsigned long kPidfdGetInfo = _IOWR(0xFF, 11, PidfdInfo);
constexpr std::uint64_t kPidfdInfoExit = 1U << 3;

int pidfd_open(std::int32_t pid) {
#ifdef SYS_pidfd_open
  return static_cast<int>(::syscall(SYS_pidfd_open, pid, 0));
#else
  errno = ENOSYS;
  return -1;
#endif
}

}  // namespace

std::int32_t current_pid() noexcept { return static_cast<std::int32_t>(::getpid()); }

ProcessIdentity self_identity() noexcept {
  static const ProcessIdentity id = [] {
    ProcessIdentity i;
    i.pid = static_cast<std::int32_t>(::getpid());
    i.start_ticks = stat_of(i.pid).start_ticks;
    return i;
  }();
  // After fork() the cached identity is the parent's: read again.
  if (id.pid != ::getpid()) {
    ProcessIdentity i;
    i.pid = static_cast<std::int32_t>(::getpid());
    i.start_ticks = stat_of(i.pid).start_ticks;
    return i;
  }
  return id;
}

std::optional<std::uint64_t> process_start_ticks(std::int32_t pid) noexcept {
  if (pid <= 0) return std::nullopt;
  try {
    const StatFields f = stat_of(pid);
    if (!f.ok) return std::nullopt;
    return f.start_ticks;
  } catch (...) {
    return std::nullopt;
  }
}

bool process_alive(const ProcessIdentity& id) noexcept {
  if (id.pid <= 0) return false;
  try {
    const StatFields f = stat_of(id.pid);
    return f.ok && f.start_ticks == id.start_ticks && f.state != 'Z' && f.state != 'X';
  } catch (...) {
    return false;
  }
}

const char* to_string(RunState s) noexcept {
  switch (s) {
    case RunState::Running:
      return "running";
    case RunState::Stopped:
      return "stopped";
    case RunState::Traced:
      return "traced";
    case RunState::Zombie:
      return "zombie";
    case RunState::Gone:
      return "gone";
  }
  return "?";
}

RunState run_state_of(char c) noexcept {
  switch (c) {
    case 'R':
    case 'S':
    case 'D':
    case 'I':
    case 'W':
    case 'P':
      return RunState::Running;
    case 'T':
      return RunState::Stopped;
    case 't':
      return RunState::Traced;
    case 'Z':
      return RunState::Zombie;
    default:
      return RunState::Gone;
  }
}

RunState process_run_state(const ProcessIdentity& id) noexcept {
  if (id.pid <= 0) return RunState::Gone;
  try {
    const StatFields f = stat_of(id.pid);
    if (!f.ok || f.start_ticks != id.start_ticks) return RunState::Gone;
    return run_state_of(f.state);
  } catch (...) {
    return RunState::Gone;
  }
}

std::string self_command_line(std::size_t max) {
  std::string s = read_small_file("/proc/self/cmdline", max + 1);
  while (!s.empty() && s.back() == '\0') s.pop_back();
  std::replace(s.begin(), s.end(), '\0', ' ');
  if (s.size() > max) s.resize(max);
  return s;
}

std::string self_process_name() {
  std::string s = read_small_file("/proc/self/comm", 64);
  while (!s.empty() && (s.back() == '\n' || s.back() == '\0')) s.pop_back();
  return s;
}

std::int64_t unix_now_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

std::int64_t start_time_unix_ns(std::uint64_t start_ticks) noexcept {
  // Boot time in wall-clock terms: now (realtime) - time since boot (CLOCK_BOOTTIME counts
  // suspend, as the start ticks do).
  timespec boot{};
  ::clock_gettime(CLOCK_BOOTTIME, &boot);
  const std::int64_t since_boot =
      static_cast<std::int64_t>(boot.tv_sec) * kNanosPerSecond + boot.tv_nsec;
  const long hz = ::sysconf(_SC_CLK_TCK);
  if (hz <= 0) return unix_now_ns() - since_boot;
  // start_ticks may come from another process's memory (a segment header): a process cannot
  // have started after now, so a larger value is taken as now (no overflow, whatever it is).
  const std::int64_t tick_ns = kNanosPerSecond / hz;
  const auto ticks_now = static_cast<std::uint64_t>(since_boot / tick_ns);
  const auto start = static_cast<std::int64_t>(std::min(start_ticks, ticks_now)) * tick_ns;
  return unix_now_ns() - since_boot + start;
}

std::string format_unix_time(std::int64_t unix_ns) {
  const std::time_t t = static_cast<std::time_t>(unix_ns / kNanosPerSecond);
  std::tm tm{};
  ::localtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  return buf;
}

std::string signal_name(int signal) {
  if (const char* abbrev = ::sigabbrev_np(signal)) return std::string("SIG") + abbrev;
  return "SIG" + std::to_string(signal);
}

std::string ExitStatus::describe() const {
  if (kind == Kind::Exited) return "exited with code " + std::to_string(code);
  std::string s = "killed by signal " + std::to_string(code) + " (" + signal_name(code) + ")";
  if (core_dumped) s += ", core dumped";
  return s;
}

ExitStatus ExitStatus::from_wait_status(int status) noexcept {
  ExitStatus e;
  if (WIFSIGNALED(status)) {
    e.kind = Kind::Signaled;
    e.code = WTERMSIG(status);
    e.core_dumped = WCOREDUMP(status);
  } else {
    e.kind = Kind::Exited;
    e.code = WEXITSTATUS(status);
  }
  return e;
}

// --- ProcessWatch ---------------------------------------------------------------------------

ProcessWatch::ProcessWatch(ProcessWatch&& o) noexcept : fd_(std::exchange(o.fd_, -1)), id_(o.id_) {}
ProcessWatch& ProcessWatch::operator=(ProcessWatch&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    id_ = o.id_;
  }
  return *this;
}
ProcessWatch::~ProcessWatch() {
  if (fd_ >= 0) ::close(fd_);
}

expected<ProcessWatch, Error> ProcessWatch::open(const ProcessIdentity& id) {
  ProcessWatch w;
  w.id_ = id;
  if (id.pid <= 0) return unexpected<Error>(Error(EINVAL, "process id " + std::to_string(id.pid)));
  const int fd = pidfd_open(id.pid);
  if (fd < 0 && errno == ESRCH) {
    return unexpected<Error>(Error(ESRCH, "process " + std::to_string(id.pid) + " is gone"));
  }
  w.fd_ = fd;  // -1 when pidfd_open is unavailable: exited() then reads /proc
  // Checked after opening: if the start time matches now, the pidfd refers to that process (a
  // pidfd never moves to another process).
  const StatFields f = stat_of(id.pid);
  if (!f.ok || f.start_ticks != id.start_ticks) {
    return unexpected<Error>(
        Error(ESRCH, "process " + std::to_string(id.pid) + " is gone (pid reused)"));
  }
  return w;
}

bool ProcessWatch::exited() const noexcept {
  if (fd_ >= 0) {
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, 0);
    return r > 0 && (p.revents & (POLLIN | POLLHUP | POLLERR)) != 0;
  }
  return !process_alive(id_);
}

std::optional<ExitStatus> ProcessWatch::exit_status(const char** source) const {
  if (!exited()) return std::nullopt;
  // The kernel gives the status to a pidfd holder once the parent has reaped the process; until
  // then the zombie's /proc entry shows it. Asked in the order kernel, zombie, kernel, the
  // parent reaping in between cannot hide it.
  const auto from_pidfd = [&]() -> std::optional<ExitStatus> {
    if (fd_ < 0) return std::nullopt;
    PidfdInfo info{};
    info.mask = kPidfdInfoExit;
    if (::ioctl(fd_, kPidfdGetInfo, &info) == 0 && (info.mask & kPidfdInfoExit) != 0) {
      if (source != nullptr) *source = "pidfd";
      return ExitStatus::from_wait_status(info.exit_code);
    }
    return std::nullopt;
  };
  if (auto st = from_pidfd()) return st;
  const StatFields f = stat_of(id_.pid);
  if (f.ok && f.start_ticks == id_.start_ticks && f.state == 'Z' && f.exit_code >= 0) {
    if (source != nullptr) *source = "zombie";
    return ExitStatus::from_wait_status(f.exit_code);
  }
  return from_pidfd();
}

int wait_readable(const int* fds, std::size_t n, Nanos deadline_ns, bool* readable) noexcept {
  thread_local std::vector<pollfd> pfds;
  try {
    pfds.resize(n);
  } catch (...) {
    return -ENOMEM;
  }
  for (std::size_t i = 0; i < n; ++i) {
    pfds[i] = pollfd{fds[i], POLLIN, 0};  // negative descriptors are ignored by poll
    readable[i] = false;
  }
  for (;;) {
    const Nanos now = now_ns();
    const Nanos left = deadline_ns > now ? deadline_ns - now : 0;
    const timespec ts{static_cast<time_t>(left / kNanosPerSecond),
                      static_cast<long>(left % kNanosPerSecond)};
    const int r = ::ppoll(pfds.data(), n, &ts, nullptr);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return -errno;
    int ready = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (fds[i] >= 0 && (pfds[i].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
        readable[i] = true;
        ++ready;
      }
    }
    return ready;
  }
}

// --- exit recorder --------------------------------------------------------------------------

namespace {

std::atomic<ExitRecorder> g_recorder{nullptr};
std::atomic<bool> g_recorded{false};
static_assert(std::atomic<ExitRecorder>::is_always_lock_free);
static_assert(std::atomic<bool>::is_always_lock_free);

constexpr int kRecordedSignals[] = {SIGTERM, SIGINT,  SIGHUP,  SIGQUIT, SIGABRT, SIGSEGV,
                                    SIGBUS,  SIGFPE,  SIGILL,  SIGTRAP, SIGSYS,  SIGPIPE,
                                    SIGALRM, SIGUSR1, SIGUSR2, SIGXCPU, SIGXFSZ};

void record_once(ExitStatus::Kind kind, int code) noexcept {
  if (g_recorded.exchange(true)) return;
  if (ExitRecorder r = g_recorder.load()) r(kind, code);
}

extern "C" void on_fatal_signal(int sig) {
  const int saved = errno;
  record_once(ExitStatus::Kind::Signaled, sig);
  // Die of the same signal: default action, then raise it again (it is blocked while this
  // handler runs and delivered when the handler returns; for a fault, the access faults again).
  struct sigaction sa {};
  sa.sa_handler = SIG_DFL;
  sigemptyset(&sa.sa_mask);
  sigaction(sig, &sa, nullptr);
  ::raise(sig);
  errno = saved;
}

extern "C" void on_process_exit(int status, void* /*arg*/) {
  record_once(ExitStatus::Kind::Exited, status & 0xff);
}

}  // namespace

void install_exit_recorder(ExitRecorder recorder) noexcept {
  ExitRecorder expected_null = nullptr;
  if (!g_recorder.compare_exchange_strong(expected_null, recorder)) return;
  ::on_exit(&on_process_exit, nullptr);
  for (const int sig : kRecordedSignals) {
    struct sigaction old {};
    if (sigaction(sig, nullptr, &old) != 0) continue;
    if ((old.sa_flags & SA_SIGINFO) != 0 || old.sa_handler != SIG_DFL) continue;
    struct sigaction sa {};
    sa.sa_handler = &on_fatal_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND | SA_ONSTACK;
    sigaction(sig, &sa, nullptr);
  }
}

}  // namespace vigil::platform
