#include "vigil/export/systemd_notify.hpp"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <charconv>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>

namespace vigil::exporter {

namespace {

// sun_path's size (108 on Linux): a path must fit with its NUL, an abstract name without one.
constexpr std::size_t kSunPath = sizeof(sockaddr_un::sun_path);

std::optional<std::string> env(const char* name) {
  const char* v = std::getenv(name);  // NOLINT(concurrency-mt-unsafe): control thread, read-only
  if (v == nullptr) return std::nullopt;
  return std::string(v);
}

// A positive decimal number without sign, spaces or suffix; nullopt otherwise (0 included).
std::optional<std::uint64_t> positive_decimal(std::string_view text) {
  std::uint64_t v = 0;
  const char* end = text.data() + text.size();
  const auto [p, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc{} || p != end || v == 0) return std::nullopt;
  return v;
}

void parse_socket(const std::optional<std::string>& value, SystemdSettings& s) {
  if (!value) return;
  const std::string& v = *value;
  const auto bad = [&](std::string_view why) {
    s.warnings.push_back(
        fmt::format("NOTIFY_SOCKET='{}' {}: no systemd notification is sent", v, why));
  };
  if (v.empty()) {
    bad("is empty");
  } else if (v.front() == '@') {
    if (v.size() == 1) {
      bad("names no abstract socket after '@'");
    } else if (v.size() > kSunPath) {
      bad(fmt::format("is too long ({} bytes; an abstract name holds at most {})", v.size() - 1,
                      kSunPath - 1));
    } else {
      s.address = v;
      s.address.front() = '\0';
    }
  } else if (v.front() == '/') {
    if (v.size() >= kSunPath) {
      bad(fmt::format("is too long ({} bytes; a socket path holds at most {})", v.size(),
                      kSunPath - 1));
    } else {
      s.address = v;
    }
  } else if (v.rfind("vsock:", 0) == 0) {
    bad("is a vsock address, which vigil does not speak (only Unix sockets)");
  } else {
    bad("is neither an absolute path nor an abstract socket ('@name')");
  }
}

void parse_watchdog(const SystemdEnvironment& env, int pid, SystemdSettings& s) {
  if (!env.watchdog_usec) return;
  const std::string& usec = *env.watchdog_usec;
  if (!s.notify()) {
    if (!env.notify_socket) {
      s.warnings.push_back(fmt::format(
          "WATCHDOG_USEC={} is set but NOTIFY_SOCKET is not: no keep-alive can be sent", usec));
    }
    return;  // a bad NOTIFY_SOCKET was said already
  }
  const auto v = positive_decimal(usec);
  constexpr auto kMaxUsec = static_cast<std::uint64_t>(std::numeric_limits<Nanos>::max() / 1000);
  if (!v) {
    s.warnings.push_back(fmt::format(
        "WATCHDOG_USEC='{}' is not a positive decimal number of microseconds: no watchdog "
        "keep-alive is sent (systemd restarts the service when its watchdog expires)",
        usec));
    return;
  }
  if (*v > kMaxUsec) {
    s.warnings.push_back(
        fmt::format("WATCHDOG_USEC={} is too large (at most {}): no watchdog keep-alive is sent",
                    usec, kMaxUsec));
    return;
  }
  if (env.watchdog_pid) {
    const auto p = positive_decimal(*env.watchdog_pid);
    if (!p || *p > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
      s.warnings.push_back(
          fmt::format("WATCHDOG_PID='{}' is not a process id: no watchdog keep-alive is sent",
                      *env.watchdog_pid));
      return;
    }
    if (static_cast<int>(*p) != pid) {
      s.warnings.push_back(fmt::format(
          "WATCHDOG_PID={} is not this process ({}): the watchdog is that process's, no "
          "keep-alive is sent from here",
          *p, pid));
      return;
    }
  }
  s.watchdog_ns = static_cast<Nanos>(*v) * 1000;
}

// One datagram to `address` through `fd`. 0 or an errno value.
int send_datagram(int fd, const std::string& address, std::string_view message) {
  sockaddr_un sa{};
  sa.sun_family = AF_UNIX;
  std::memcpy(sa.sun_path, address.data(), address.size());
  // An abstract name is exactly its bytes; a path may end at its NUL.
  const auto len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + address.size() +
                                          (address.front() == '\0' ? 0 : 1));
  // Never blocks the monitor: a full queue is a failed send (EAGAIN), said as a warning.
  const ssize_t n = ::sendto(fd, message.data(), message.size(), MSG_NOSIGNAL | MSG_DONTWAIT,
                             reinterpret_cast<const sockaddr*>(&sa), len);
  if (n < 0) return errno;
  return static_cast<std::size_t>(n) == message.size() ? 0 : EMSGSIZE;
}

int open_socket() { return ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0); }

// A status text on one line: control characters (newlines) become spaces.
std::string one_line(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  }
  return out;
}

// The first message of `r` at its own level, or all of them.
std::string reason_of(const Report& r) {
  for (const auto& m : r.status.messages()) {
    if (m.level == r.status.level() && !m.text.empty()) return m.text;
  }
  return r.status.summary();
}

}  // namespace

SystemdEnvironment SystemdEnvironment::from_process() {
  return SystemdEnvironment{.notify_socket = env("NOTIFY_SOCKET"),
                            .watchdog_usec = env("WATCHDOG_USEC"),
                            .watchdog_pid = env("WATCHDOG_PID")};
}

SystemdSettings parse_systemd_environment(const SystemdEnvironment& env, int pid) {
  SystemdSettings s;
  parse_socket(env.notify_socket, s);
  parse_watchdog(env, pid, s);
  return s;
}

std::string systemd_status_line(const ReportSet& reports) {
  const StatusLevel level = reports.worst();
  std::string line;
  if (level == StatusLevel::Ok) {
    line = fmt::format("OK: {} reports", reports.components.size());
  } else {
    const Report* first = nullptr;
    std::size_t not_ok = 0;
    for (const Report& r : reports.components) {
      if (r.status.ok()) continue;
      ++not_ok;
      if (first == nullptr && r.status.level() == level) first = &r;
    }
    line = fmt::format("{}: {}", to_string(level), first->name);
    if (const std::string why = reason_of(*first); !why.empty()) line += ": " + why;
    if (not_ok > 1) line += fmt::format(" (+{} more not OK)", not_ok - 1);
  }
  line = one_line(line);
  if (line.size() > kSystemdStatusMax) {
    line.resize(kSystemdStatusMax - 3);
    line += "...";
  }
  return line;
}

expected<bool, Error> notify_systemd(std::string_view message) {
  const SystemdSettings s =
      parse_systemd_environment(SystemdEnvironment::from_process(), ::getpid());
  if (!s.notify()) {
    if (!s.warnings.empty()) return unexpected(Error{EINVAL, s.warnings.front()});
    return false;
  }
  const int fd = open_socket();
  if (fd < 0) {
    const int err = errno;
    return unexpected(Error{err, fmt::format("systemd notify: socket(): {}", std::strerror(err))});
  }
  const int err = send_datagram(fd, s.address, message);
  ::close(fd);
  if (err != 0) {
    return unexpected(Error{
        err, fmt::format("systemd notify: cannot send to NOTIFY_SOCKET: {}", std::strerror(err))});
  }
  return true;
}

// --- the output --------------------------------------------------------------------------------

SystemdNotifyOutput::SystemdNotifyOutput(SystemdNotifyOptions options)
    : options_(std::move(options)),
      settings_(parse_systemd_environment(options_.environment, ::getpid())) {}

SystemdNotifyOutput::~SystemdNotifyOutput() {
  std::lock_guard lock(mutex_);
  if (fd_ >= 0) ::close(fd_);
}

void SystemdNotifyOutput::say(const std::string& line) const {
  if (options_.warn) {
    options_.warn(line);
  } else {
    std::fprintf(stderr, "vigil: %s\n", line.c_str());
  }
}

expected<void, Error> SystemdNotifyOutput::start(OutputContext& /*context*/) {
  for (const std::string& w : settings_.warnings) say(w);
  ready_.store(false, std::memory_order_relaxed);
  status_.clear();
  last_keepalive_ns_.reset();
  supervisor_cycles_.reset();
  withheld_ = false;
  const Nanos half = settings_.watchdog_ns / 2;
  if (half > 0 && options_.monitor_period_ns >= half) {
    say(fmt::format(
        "WATCHDOG_USEC={}: half of it ({}) is not longer than the monitor's period ({}), which "
        "sends the keep-alives: they may come too late (make WatchdogSec= more than twice the "
        "monitor period)",
        settings_.watchdog_ns / 1000, format_nanos(static_cast<double>(half)),
        format_nanos(static_cast<double>(options_.monitor_period_ns))));
  }
  if (!settings_.notify()) return {};
  std::lock_guard lock(mutex_);
  if (fd_ < 0) fd_ = open_socket();
  if (fd_ < 0) {
    say(fmt::format("systemd notify: socket(): {}: no notification is sent", std::strerror(errno)));
  }
  send_failed_ = false;
  return {};
}

bool SystemdNotifyOutput::send_locked(std::string_view message) {
  if (fd_ < 0) return false;
  if (const int err = send_datagram(fd_, settings_.address, message); err != 0) {
    if (!send_failed_) {
      say(
          fmt::format("systemd notify: cannot send to NOTIFY_SOCKET={}: {} (said once until a "
                      "send succeeds)",
                      *options_.environment.notify_socket, std::strerror(err)));
    }
    send_failed_ = true;
    return false;
  }
  send_failed_ = false;
  return true;
}

bool SystemdNotifyOutput::notify(std::string_view message) {
  std::lock_guard lock(mutex_);
  return send_locked(message);
}

// Whether the supervisor drained since the latest keep-alive (the monitor did: this is one of its
// cycles). Without a supervisor's report the monitor's cycles alone count.
bool SystemdNotifyOutput::progressing(const Snapshot& snapshot, Nanos now) {
  const Report* sup = nullptr;
  for (const Report& r : snapshot.reports.components) {
    if (r.kind == ReportKind::Supervisor) {
      sup = &r;
      break;
    }
  }
  if (sup == nullptr) return true;
  const Nanos half = settings_.watchdog_ns / 2;
  const std::uint64_t cycles = sup->counters.cycles;
  std::string why;
  if (cycles == 0) {
    why = "has made no cycle yet";
  } else if (supervisor_cycles_ && cycles <= *supervisor_cycles_) {
    why = fmt::format("made no cycle since the last keep-alive {} ago (still {} cycles)",
                      format_nanos(static_cast<double>(now - last_keepalive_ns_.value_or(now))),
                      cycles);
  } else if (sup->silence_ns > half) {
    why = fmt::format("is silent for {}", format_nanos(static_cast<double>(sup->silence_ns)));
  }
  if (why.empty()) {
    supervisor_cycles_ = cycles;  // the baseline of the next keep-alive
    withheld_ = false;
    return true;
  }
  if (!withheld_) {
    say(
        fmt::format("systemd watchdog: keep-alive withheld: the supervisor '{}' {}; systemd "
                    "restarts the service when WatchdogSec= passes without one",
                    sup->name, why));
  }
  withheld_ = true;
  return false;
}

bool SystemdNotifyOutput::keep_alive_due(const Snapshot& snapshot, Nanos now) {
  if (settings_.watchdog_ns <= 0) return false;
  // Due a tenth early: a monitor cycle that comes a hair before half the interval would
  // otherwise push the keep-alive a whole monitor period later.
  const Nanos half = settings_.watchdog_ns / 2;
  const bool due = !last_keepalive_ns_ || now - *last_keepalive_ns_ >= half - half / 10;
  return due && progressing(snapshot, now);
}

void SystemdNotifyOutput::publish(const Snapshot& snapshot) {
  if (!settings_.notify()) return;
  const Nanos now = options_.clock.now();
  std::string message;
  if (!ready()) message += "READY=1\n";
  std::string status = systemd_status_line(snapshot.reports);
  if (status != status_) message += "STATUS=" + status + "\n";
  const bool keep_alive = keep_alive_due(snapshot, now);
  if (keep_alive) message += "WATCHDOG=1\n";
  // What was not sent is sent again with the next cycle (READY, STATUS) or when due (WATCHDOG).
  if (message.empty() || !notify(message)) return;
  ready_.store(true, std::memory_order_relaxed);
  status_ = std::move(status);
  if (keep_alive) {
    last_keepalive_ns_ = now;
    keepalives_.fetch_add(1, std::memory_order_relaxed);
  }
}

void SystemdNotifyOutput::stop(const Snapshot& final_snapshot) {
  if (!settings_.notify()) return;
  std::string message = "STOPPING=1\n";
  if (std::string status = systemd_status_line(final_snapshot.reports); status != status_) {
    message += "STATUS=" + status + "\n";
    status_ = std::move(status);
  }
  std::lock_guard lock(mutex_);
  (void)send_locked(message);
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

}  // namespace vigil::exporter
