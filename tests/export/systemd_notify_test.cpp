#include "vigil/export/systemd_notify.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "support/fake_clock.hpp"
#include "vigil/service/supervision_service.hpp"

using namespace vigil;
using exporter::SystemdEnvironment;
using exporter::SystemdNotifyOptions;
using exporter::SystemdNotifyOutput;

namespace {

// systemd's end of the protocol: a Unix datagram socket bound in a fresh temporary directory
// (its path is what NOTIFY_SOCKET holds), or in the abstract namespace.
class NotifySocket {
 public:
  explicit NotifySocket(bool abstract = false) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    REQUIRE(fd_ >= 0);
    static int counter = 0;
    const std::string tag = std::to_string(::getpid()) + "." + std::to_string(++counter);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    socklen_t len = 0;
    if (abstract) {
      name_ = "@vigil-notify-test." + tag;
      std::memcpy(sa.sun_path + 1, name_.data() + 1, name_.size() - 1);
      len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + name_.size());
    } else {
      dir_ = std::filesystem::temp_directory_path() / ("vigil-notify." + tag);
      std::filesystem::remove_all(dir_);
      std::filesystem::create_directories(dir_);
      name_ = (dir_ / "notify").string();
      REQUIRE(name_.size() < sizeof(sa.sun_path));
      std::memcpy(sa.sun_path, name_.c_str(), name_.size() + 1);
      len = sizeof sa;
    }
    REQUIRE(::bind(fd_, reinterpret_cast<const sockaddr*>(&sa), len) == 0);
  }
  ~NotifySocket() {
    ::close(fd_);
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  [[nodiscard]] const std::string& name() const { return name_; }

  // The datagrams queued now, or, when none is, the first to come within `wait_ms` and those
  // queued with it. The output sends from the caller's thread, so a datagram is queued by the
  // time publish() returns.
  std::vector<std::string> receive(int wait_ms = 0) {
    std::vector<std::string> out;
    if (!wait_readable(wait_ms)) return out;
    do {
      out.push_back(read_one());
    } while (wait_readable(0));
    return out;
  }
  // Every datagram that arrives within `window_ms`.
  std::vector<std::string> collect(int window_ms) {
    std::vector<std::string> out;
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(window_ms);
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                            end - std::chrono::steady_clock::now())
                            .count();
      if (left <= 0 || !wait_readable(static_cast<int>(left))) break;
      out.push_back(read_one());
    }
    while (wait_readable(0)) out.push_back(read_one());
    return out;
  }

 private:
  bool wait_readable(int ms) {
    pollfd p{fd_, POLLIN, 0};
    return ::poll(&p, 1, ms) > 0;
  }
  std::string read_one() {
    char buf[4096];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    REQUIRE(n >= 0);
    return {buf, static_cast<std::size_t>(n)};
  }

  int fd_ = -1;
  std::string name_;
  std::filesystem::path dir_;
};

// The lines of all datagrams, in order.
std::vector<std::string> lines_of(const std::vector<std::string>& datagrams) {
  std::vector<std::string> out;
  for (const std::string& d : datagrams) {
    std::size_t start = 0;
    while (start < d.size()) {
      std::size_t end = d.find('\n', start);
      if (end == std::string::npos) end = d.size();
      if (end > start) out.push_back(d.substr(start, end - start));
      start = end + 1;
    }
  }
  return out;
}

std::size_t count(const std::vector<std::string>& lines, const std::string& line) {
  return static_cast<std::size_t>(std::count(lines.begin(), lines.end(), line));
}

std::vector<std::string> with_prefix(const std::vector<std::string>& lines,
                                     const std::string& prefix) {
  std::vector<std::string> out;
  for (const auto& l : lines) {
    if (l.rfind(prefix, 0) == 0) out.push_back(l);
  }
  return out;
}

bool mentions(const std::vector<std::string>& warnings, const std::string& what) {
  return std::any_of(warnings.begin(), warnings.end(),
                     [&](const std::string& w) { return w.find(what) != std::string::npos; });
}

Report report(std::string name, ReportKind kind = ReportKind::Component) {
  Report r;
  r.kind = kind;
  r.name = std::move(name);
  return r;
}

// A monitor cycle: one component and the supervisor's report with `supervisor_cycles`.
exporter::Snapshot snapshot(std::uint64_t cycle, std::uint64_t supervisor_cycles,
                            Nanos supervisor_silence_ns = 0) {
  exporter::Snapshot s;
  s.cycle = cycle;
  s.reports.cycle = cycle;
  s.reports.components.push_back(report("motor"));
  Report sup = report("vigil.supervisor", ReportKind::Supervisor);
  sup.counters.cycles = supervisor_cycles;
  sup.silence_ns = supervisor_silence_ns;
  s.reports.components.push_back(std::move(sup));
  return s;
}

// An output on `socket` with a fake clock and the warnings kept.
struct Fixture {
  NotifySocket socket;
  test::FakeClock clock;
  std::vector<std::string> warnings;
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{}};
  exporter::OutputContext context{aggregator};

  std::unique_ptr<SystemdNotifyOutput> make(std::optional<std::string> watchdog_usec = {}) {
    return std::make_unique<SystemdNotifyOutput>(SystemdNotifyOptions{
        .environment = {.notify_socket = socket.name(), .watchdog_usec = std::move(watchdog_usec)},
        .clock = clock.clock(),
        .warn = [this](const std::string& w) { warnings.push_back(w); }});
  }
};

}  // namespace

TEST_CASE("systemd environment: paths and abstract names are accepted, bad variables are named",
          "[export][systemd]") {
  const int pid = ::getpid();
  const auto parse = [&](SystemdEnvironment e) {
    return exporter::parse_systemd_environment(e, pid);
  };
  SECTION("unset: nothing to do, nothing to say") {
    const auto s = parse({});
    CHECK_FALSE(s.notify());
    CHECK(s.watchdog_ns == 0);
    CHECK(s.warnings.empty());
  }
  SECTION("an absolute path and an abstract name") {
    auto s = parse({.notify_socket = "/run/systemd/notify"});
    CHECK(s.address == "/run/systemd/notify");
    CHECK(s.warnings.empty());
    s = parse({.notify_socket = "@vigil/notify"});
    CHECK(s.address == std::string("\0vigil/notify", 13));
    CHECK(s.warnings.empty());
    // An abstract name of 107 bytes fits sun_path (108) without a NUL; a path of 107 with one.
    CHECK(parse({.notify_socket = "@" + std::string(107, 'a')}).notify());
    CHECK(parse({.notify_socket = "/" + std::string(106, 'a')}).notify());
  }
  SECTION("malformed NOTIFY_SOCKET: a warning naming it, no notification") {
    for (const std::string& bad :
         {std::string(), std::string("run/notify"), std::string("@"), "/" + std::string(107, 'a'),
          "@" + std::string(108, 'a'), std::string("vsock:2:1234")}) {
      const auto s = parse({.notify_socket = bad, .watchdog_usec = "1000000"});
      INFO("NOTIFY_SOCKET='" << bad << "'");
      CHECK_FALSE(s.notify());
      CHECK(s.watchdog_ns == 0);
      REQUIRE(s.warnings.size() == 1);
      CHECK(s.warnings.front().rfind("NOTIFY_SOCKET=", 0) == 0);
    }
    CHECK(mentions(parse({.notify_socket = ""}).warnings, "is empty"));
    CHECK(mentions(parse({.notify_socket = "/" + std::string(120, 'a')}).warnings, "too long"));
  }
  SECTION("WATCHDOG_USEC: microseconds, positive, decimal") {
    auto s = parse({.notify_socket = "/run/n", .watchdog_usec = "2000000"});
    CHECK(s.watchdog_ns == 2 * kNanosPerSecond);
    CHECK(s.warnings.empty());
    for (const char* bad : {"0", "-5", "abc", "", "10s", " 100", "99999999999999999999"}) {
      s = parse({.notify_socket = "/run/n", .watchdog_usec = bad});
      INFO("WATCHDOG_USEC='" << bad << "'");
      CHECK(s.notify());  // the rest of the protocol goes on
      CHECK(s.watchdog_ns == 0);
      REQUIRE(s.warnings.size() == 1);
      CHECK(s.warnings.front().rfind("WATCHDOG_USEC=", 0) == 0);
    }
  }
  SECTION("WATCHDOG_PID: honoured only when it is this process") {
    auto s = parse(
        {.notify_socket = "/run/n", .watchdog_usec = "1000", .watchdog_pid = std::to_string(pid)});
    CHECK(s.watchdog_ns == 1000 * 1000);
    CHECK(s.warnings.empty());
    s = parse({.notify_socket = "/run/n",
               .watchdog_usec = "1000",
               .watchdog_pid = std::to_string(pid + 1)});
    CHECK(s.watchdog_ns == 0);
    CHECK(mentions(s.warnings, "WATCHDOG_PID=" + std::to_string(pid + 1) + " is not this process"));
    s = parse({.notify_socket = "/run/n", .watchdog_usec = "1000", .watchdog_pid = "me"});
    CHECK(s.watchdog_ns == 0);
    CHECK(mentions(s.warnings, "WATCHDOG_PID='me'"));
  }
  SECTION("WATCHDOG_USEC without NOTIFY_SOCKET is said") {
    CHECK(mentions(parse({.watchdog_usec = "1000"}).warnings, "NOTIFY_SOCKET is not"));
  }
}

TEST_CASE("systemd status line: the worst level, its first report and message, on one line",
          "[export][systemd]") {
  ReportSet set;
  set.components.push_back(report("camera"));
  set.components.push_back(report("motor"));
  set.components.push_back(report("arm"));
  CHECK(exporter::systemd_status_line(set) == "OK: 3 reports");
  set.components[0].merge(StatusLevel::Warn, "near overrun");
  CHECK(exporter::systemd_status_line(set) == "WARN: camera: near overrun");
  set.components[1].merge(StatusLevel::Warn, "drops");
  set.components[1].merge(StatusLevel::Error, "3 overruns\nin the window");
  CHECK(exporter::systemd_status_line(set) ==
        "ERROR: motor: 3 overruns in the window (+1 more not OK)");
  set.components[2].merge(StatusLevel::Error, std::string(400, 'x'));
  const std::string long_line = exporter::systemd_status_line(set);
  CHECK(long_line.size() <= exporter::kSystemdStatusMax);
  CHECK(long_line.find('\n') == std::string::npos);
}

TEST_CASE("systemd notify: READY once after the first cycle, STATUS when it changes, STOPPING",
          "[export][systemd]") {
  Fixture f;
  auto out = f.make();
  REQUIRE(out->start(f.context));
  CHECK(f.socket.receive().empty());  // nothing before the first cycle
  CHECK_FALSE(out->ready());

  out->publish(snapshot(1, 10));
  auto first = f.socket.receive(1000);
  REQUIRE(first.size() == 1);  // one datagram
  CHECK(lines_of(first) == std::vector<std::string>{"READY=1", "STATUS=OK: 2 reports"});
  CHECK(out->ready());

  out->publish(snapshot(2, 20));        // same status: nothing to say
  CHECK(f.socket.receive(50).empty());  // (a datagram would be queued already)

  auto warn = snapshot(3, 30);
  warn.reports.components[0].merge(StatusLevel::Warn, "near overrun");
  out->publish(warn);
  out->publish(warn);
  auto changed = lines_of(f.socket.receive(1000));
  CHECK(changed == std::vector<std::string>{"STATUS=WARN: motor: near overrun"});

  CHECK(out->trigger_watchdog());
  CHECK(lines_of(f.socket.receive(1000)) == std::vector<std::string>{"WATCHDOG=trigger"});

  out->stop(snapshot(4, 40));
  const auto last = lines_of(f.socket.receive(1000));
  CHECK(count(last, "STOPPING=1") == 1);
  CHECK(count(last, "STATUS=OK: 2 reports") == 1);
  CHECK(count(last, "READY=1") == 0);
  CHECK(f.warnings.empty());
  CHECK(out->keepalives() == 0);  // no WATCHDOG_USEC: no keep-alive
  CHECK_FALSE(out->notify("STATUS=after stop"));
}

TEST_CASE("systemd notify: an abstract NOTIFY_SOCKET is reached", "[export][systemd]") {
  NotifySocket socket(/*abstract=*/true);
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{}};
  exporter::OutputContext context{aggregator};
  SystemdNotifyOutput out(SystemdNotifyOptions{.environment = {.notify_socket = socket.name()}});
  REQUIRE(out.start(context));
  out.publish(snapshot(1, 1));
  CHECK(count(lines_of(socket.receive(1000)), "READY=1") == 1);
  out.stop(snapshot(2, 2));
  CHECK(count(lines_of(socket.receive(1000)), "STOPPING=1") == 1);
}

TEST_CASE("systemd watchdog: keep-alive at half the interval while the supervisor drains",
          "[export][systemd]") {
  Fixture f;
  auto out = f.make("1000000");  // 1 s: a keep-alive every 500 ms
  REQUIRE(out->settings().watchdog_ns == kNanosPerSecond);
  REQUIRE(out->start(f.context));
  std::uint64_t cycle = 0;
  std::uint64_t drained = 0;
  // A monitor cycle every 100 ms of the fake clock for `ms`; the supervisor drains 10 times per
  // cycle when `draining`.
  const auto run = [&](int ms, bool draining, Nanos silence_ns = 0) {
    for (int t = 0; t < ms; t += 100) {
      if (draining) drained += 10;
      out->publish(snapshot(++cycle, drained, silence_ns));
      f.clock.advance(100 * kNanosPerMilli);
    }
    return with_prefix(lines_of(f.socket.receive()), "WATCHDOG=");
  };

  SECTION("every 500 ms while it drains") {
    const auto alive = run(3000, true);
    // At 0, 500, ..., 2500 ms: the first with READY.
    CHECK(alive.size() == 6);
    CHECK(count(alive, "WATCHDOG=1") == alive.size());
    CHECK(out->keepalives() == 6);
    CHECK(f.warnings.empty());
  }
  SECTION("withheld while the supervisor makes no cycle, back when it drains again") {
    CHECK(run(1000, true).size() == 2);
    // The keep-alive due at 1000 ms was earned (cycles drained since the one at 500 ms); then
    // none while the count stands still.
    const auto stalled = run(3000, false);
    CHECK(stalled.size() == 1);
    REQUIRE(f.warnings.size() == 1);  // said once per stall
    CHECK(mentions(f.warnings,
                   "keep-alive withheld: the supervisor 'vigil.supervisor' made no cycle"));
    const auto back = run(1000, true);
    CHECK(back.size() >= 1);
    CHECK(back.size() <= 3);
  }
  SECTION("withheld while the supervisor's report says it is silent") {
    CHECK(run(1000, true).size() == 2);
    // Cycles counted but silent for 2 s: a stale report (e.g. the monitor reads an old count).
    CHECK(run(2000, true, 2 * kNanosPerSecond).empty());
    CHECK(mentions(f.warnings, "is silent for"));
  }
  SECTION("withheld from the start when the supervisor never drained") {
    CHECK(run(2000, false).empty());
    CHECK(mentions(f.warnings, "has made no cycle yet"));
    CHECK(out->ready());  // READY and STATUS were still sent
  }
}

TEST_CASE("systemd watchdog: a monitor period too long for the interval is said",
          "[export][systemd]") {
  NotifySocket socket;
  std::vector<std::string> warnings;
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{}};
  exporter::OutputContext context{aggregator};
  SystemdNotifyOutput out(SystemdNotifyOptions{
      .environment = {.notify_socket = socket.name(), .watchdog_usec = "1000000"},
      .monitor_period_ns = kNanosPerSecond,
      .warn = [&](const std::string& w) { warnings.push_back(w); }});
  REQUIRE(out.start(context));
  CHECK(mentions(warnings, "WATCHDOG_USEC=1000000: half of it"));
  out.stop({});
}

TEST_CASE("systemd notify: an unreachable socket is a warning once, supervision goes on",
          "[export][systemd]") {
  std::vector<std::string> warnings;
  supervisor::ComponentAggregator aggregator{supervisor::AggregatorOptions{}};
  exporter::OutputContext context{aggregator};
  const auto nobody =
      std::filesystem::temp_directory_path() / ("vigil-notify-none." + std::to_string(::getpid()));
  SystemdNotifyOutput out(
      SystemdNotifyOptions{.environment = {.notify_socket = nobody.string()},
                           .warn = [&](const std::string& w) { warnings.push_back(w); }});
  REQUIRE(out.start(context));
  out.publish(snapshot(1, 1));
  out.publish(snapshot(2, 2));
  CHECK_FALSE(out.ready());  // READY is tried again with the next cycle
  REQUIRE(warnings.size() == 1);
  CHECK(mentions(warnings, "cannot send to NOTIFY_SOCKET=" + nobody.string()));
  out.stop(snapshot(3, 3));
}

TEST_CASE("systemd notify through the service: READY, keep-alives, stall, STOPPING",
          "[export][systemd][service]") {
  NotifySocket socket;
  service::SupervisionServiceOptions o;
  o.supervisor_period_ns = 5 * kNanosPerMilli;
  o.monitor_period_ns = 20 * kNanosPerMilli;
  o.summary_file = nullptr;
  // WatchdogSec=200ms: a keep-alive about every 100 ms.
  o.systemd_environment =
      SystemdEnvironment{.notify_socket = socket.name(), .watchdog_usec = "200000"};
  ComponentRegistry registry;
  o.registry = &registry;
  service::SupervisionService service(std::move(o));
  REQUIRE(service.systemd() != nullptr);
  CHECK(service.systemd()->settings().warnings.empty());
  REQUIRE(service.start());

  const auto healthy = lines_of(socket.collect(1000));
  CHECK(count(healthy, "READY=1") == 1);
  CHECK(with_prefix(healthy, "STATUS=").size() >= 1);
  // ~10 in one second; generous bounds for a loaded machine.
  const std::size_t alive = count(healthy, "WATCHDOG=1");
  CHECK(alive >= 4);
  CHECK(alive <= 14);

  // The supervisor's thread stops draining while the monitor goes on: its report stops
  // counting, so the keep-alive stops (one may still be due from cycles drained before).
  service.source().stop();
  (void)socket.collect(150);
  const auto stalled = lines_of(socket.collect(600));
  CHECK(count(stalled, "WATCHDOG=1") == 0);
  CHECK(service.reports().cycle > 20);  // the monitor still cycled

  (void)service.stop();
  const auto stopping = lines_of(socket.receive(1000));
  CHECK(count(stopping, "STOPPING=1") == 1);
  CHECK(count(stopping, "READY=1") == 0);
}

TEST_CASE("systemd notify through the service: bad variables are warnings, supervision goes on",
          "[export][systemd][service]") {
  ComponentRegistry registry;
  service::SupervisionServiceOptions o;
  o.registry = &registry;
  o.monitor_thread = false;
  o.summary_file = nullptr;
  o.systemd_environment =
      SystemdEnvironment{.notify_socket = "relative/notify", .watchdog_usec = "garbage"};
  service::SupervisionService service(std::move(o));
  REQUIRE(service.systemd() != nullptr);
  CHECK(mentions(service.systemd()->settings().warnings, "NOTIFY_SOCKET='relative/notify'"));
  REQUIRE(service.start());
  const ReportSet r = service.step();
  CHECK(r.cycle == 1);
  CHECK_FALSE(service.systemd()->ready());
  (void)service.stop();
}

TEST_CASE("systemd notify through the service: only with NOTIFY_SOCKET, unless turned off",
          "[export][systemd][service]") {
  ComponentRegistry registry;
  service::SupervisionServiceOptions o;
  o.registry = &registry;
  o.summary_file = nullptr;
  o.systemd_environment = SystemdEnvironment{.watchdog_usec = "1000"};
  CHECK(service::SupervisionService(o).systemd() == nullptr);
  o.systemd_environment = SystemdEnvironment{.notify_socket = "/run/n"};
  CHECK(service::SupervisionService(o).systemd() != nullptr);
  o.systemd_notify = false;
  CHECK(service::SupervisionService(o).systemd() == nullptr);
}
