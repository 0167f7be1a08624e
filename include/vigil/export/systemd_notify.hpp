#pragma once
/// @file
/// systemd's notify protocol (sd_notify(3)) as an output: `SystemdNotifyOutput` tells the service
/// manager when supervision is ready, what its status is, that it still makes progress (the
/// watchdog keep-alive) and when it stops. No libsystemd: the protocol is one datagram of
/// newline-separated `KEY=VALUE` lines sent to the Unix socket named by `NOTIFY_SOCKET`.
///
/// | message | when |
/// | --- | --- |
/// | `READY=1` | after the first complete monitor cycle (its snapshot reached the outputs) |
/// | `STATUS=<line>` | with READY, then whenever the line changes (`systemd_status_line()`) |
/// | `WATCHDOG=1` | at half of `WATCHDOG_USEC`, only while the monitor publishes cycles and the
/// supervisor's report shows it drains | | `WATCHDOG=trigger` | `trigger_watchdog()`: a program (a
/// reaction) asks systemd to act now | | `STOPPING=1` | when the pipeline stops |
///
/// `SupervisionService` adds one by itself when the process's environment has `NOTIFY_SOCKET`
/// (`SupervisionServiceOptions::systemd_notify`), so `vigil supervise`, `vigil demo` and a
/// deployment's `System` speak it under a `Type=notify` unit (docs/guide/systemd.md).
///
/// Bad settings (a malformed `NOTIFY_SOCKET`, a `WATCHDOG_USEC` of 0 or garbage) are warnings
/// naming the variable; supervision goes on without what they would have enabled. A send that
/// fails is a warning too (once until a send succeeds again), never an error of the pipeline.
///
/// Threads: as every `Output` (start and stop on the control thread, publish on the monitor's);
/// `notify()` and `trigger_watchdog()` from any thread. Nothing here is RT-safe, and nothing
/// touches a real-time thread.

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/output.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::exporter {

/// The variables systemd sets for a service, as text (unset: no value). Passed explicitly so a
/// program or a test can say what the environment holds without changing the process's.
struct SystemdEnvironment {
  std::optional<std::string> notify_socket{};  ///< `NOTIFY_SOCKET`: where notifications go
  std::optional<std::string> watchdog_usec{};  ///< `WATCHDOG_USEC`: the watchdog's interval (µs)
  std::optional<std::string> watchdog_pid{};   ///< `WATCHDOG_PID`: the process it watches

  /// The process's own variables (getenv). Control thread: not safe against a concurrent
  /// setenv().
  [[nodiscard]] static SystemdEnvironment from_process();
};

/// What a `SystemdEnvironment` means, checked (`parse_systemd_environment()`).
struct SystemdSettings {
  /// The socket's address as `sockaddr_un::sun_path` holds it: a path, or an abstract name whose
  /// leading '@' became a NUL byte. Empty: nothing is sent.
  std::string address;
  /// The watchdog's interval; 0: no watchdog for this process (unset, not this process's, or
  /// bad). The keep-alive is sent every `watchdog_ns / 2`.
  Nanos watchdog_ns = 0;
  /// One line per setting that was bad or ignored, each naming its variable and what follows.
  std::vector<std::string> warnings;

  [[nodiscard]] bool notify() const noexcept { return !address.empty(); }
};

/// Checks the variables for the process `pid` (the caller's getpid()), as sd_notify(3) and
/// sd_watchdog_enabled(3) read them: `NOTIFY_SOCKET` an absolute path or an '@' abstract name that
/// fits `sun_path`; `WATCHDOG_USEC` a positive decimal number of microseconds; `WATCHDOG_PID`, when
/// set, a process id (the watchdog is this process's only when it is `pid`). Anything else is a
/// warning and the part it would enable stays off. Pure: reads nothing but its arguments.
[[nodiscard]] SystemdSettings parse_systemd_environment(const SystemdEnvironment& env, int pid);

/// The one line of `STATUS=` for a monitor cycle: the worst level, then the first report at that
/// level with its first message at that level, and how many more reports are not OK:
/// "ERROR: motor: 3 overruns in the window (+1 more not OK)", or "OK: 7 reports". Newlines and
/// control characters become spaces; at most `kSystemdStatusMax` bytes.
[[nodiscard]] std::string systemd_status_line(const ReportSet& reports);
inline constexpr std::size_t kSystemdStatusMax = 200;

/// Sends `message` (newline-separated `KEY=VALUE` lines) to the process's `NOTIFY_SOCKET`, as
/// sd_notify(3) does. Returns false when the variable is unset (nothing to do), an error when it
/// is malformed or the send fails. Any thread; not RT-safe (a socket per call).
expected<bool, Error> notify_systemd(std::string_view message);

/// The options of a `SystemdNotifyOutput`.
struct SystemdNotifyOptions {
  /// What the environment holds; all unset (the default): the output sends nothing. The service
  /// passes `SystemdEnvironment::from_process()`.
  SystemdEnvironment environment{};
  /// The monitor's period, to check that half of the watchdog's interval is longer (each
  /// keep-alive is sent from a monitor cycle); 0: not checked.
  Nanos monitor_period_ns = 0;
  /// The time between keep-alives is measured on this clock: real time, whatever clock the
  /// monitor uses.
  Clock clock = Clock::system();
  /// Receives every warning (a bad variable, a failed send, a withheld keep-alive) as one line
  /// without a prefix; empty: "vigil: <line>" on stderr. Called on the thread that found it.
  std::function<void(const std::string&)> warn{};
};

/**
 * systemd's notify protocol as an output (see the file comment for what it sends and when).
 *
 * The keep-alive is driven by the monitor's cycles, not by a timer of its own: a cycle that
 * reaches publish() sends `WATCHDOG=1` when half of the interval (less a tenth of it, against
 * the monitor's jitter) has passed since the last one and the supervisor made progress since then
 * (its report, of kind `ReportKind::Supervisor`, counts more cycles and its silence, when known, is
 * shorter than half the interval). A stalled monitor (or an output that blocks it) calls publish()
 * no more and a stalled supervisor stops counting, so either one stops the keep-alive and systemd
 * restarts the service after `WatchdogSec=`. The monitor's period must therefore be shorter than
 * half of it (checked at start: a warning otherwise).
 *
 * **Example**:
 * ```cpp
 * // What SupervisionService does when NOTIFY_SOCKET is set:
 * service.add_output<vigil::exporter::SystemdNotifyOutput>(vigil::exporter::SystemdNotifyOptions{
 *     .environment = vigil::exporter::SystemdEnvironment::from_process(),
 *     .monitor_period_ns = service.options().monitor_period_ns});
 * ```
 */
class SystemdNotifyOutput final : public Output {
 public:
  explicit SystemdNotifyOutput(SystemdNotifyOptions options);
  ~SystemdNotifyOutput() override;
  SystemdNotifyOutput(const SystemdNotifyOutput&) = delete;
  SystemdNotifyOutput& operator=(const SystemdNotifyOutput&) = delete;

  /// Says the settings' warnings and opens the socket. Never fails: without a usable socket the
  /// output sends nothing, and supervision goes on.
  expected<void, Error> start(OutputContext& context) override;
  /// READY=1 (first cycle), STATUS= (when changed), WATCHDOG=1 (when due and progressing).
  void publish(const Snapshot& snapshot) override;
  /// STOPPING=1 with the final status; closes the socket.
  void stop(const Snapshot& final_snapshot) override;

  /// Sends `message` now (e.g. "EXTEND_TIMEOUT_USEC=5000000"). False when the output sends
  /// nothing (no socket, not started) or the send failed (a warning said why). Any thread.
  bool notify(std::string_view message);
  /// Sends `WATCHDOG=trigger`: systemd acts as if the watchdog's interval had passed (the unit's
  /// `WatchdogSignal=`, then its `Restart=`). For a reaction that wants the service restarted.
  /// Any thread.
  bool trigger_watchdog() { return notify("WATCHDOG=trigger"); }

  /// The settings read from the environment (address, watchdog interval, warnings).
  [[nodiscard]] const SystemdSettings& settings() const noexcept { return settings_; }
  /// Whether READY=1 was sent (since the latest start()). Any thread.
  [[nodiscard]] bool ready() const noexcept { return ready_.load(std::memory_order_relaxed); }
  /// Keep-alives sent so far; any thread.
  [[nodiscard]] std::uint64_t keepalives() const noexcept {
    return keepalives_.load(std::memory_order_relaxed);
  }

 private:
  void say(const std::string& line) const;
  bool send_locked(std::string_view message);
  [[nodiscard]] bool progressing(const Snapshot& snapshot, Nanos now);
  [[nodiscard]] bool keep_alive_due(const Snapshot& snapshot, Nanos now);

  SystemdNotifyOptions options_;
  SystemdSettings settings_;
  mutable std::mutex mutex_;  // guards fd_ and send_failed_: sends come from any thread
  int fd_ = -1;
  bool send_failed_ = false;
  // Monitor thread's state (publish), reset by start().
  // Written by the monitor's thread, read by any; relaxed: a flag that orders no other data.
  std::atomic<bool> ready_{false};
  std::string status_;
  std::optional<Nanos> last_keepalive_ns_;
  std::optional<std::uint64_t> supervisor_cycles_;  // at the latest keep-alive
  bool withheld_ = false;                     // the latest due keep-alive was withheld (said once)
  std::atomic<std::uint64_t> keepalives_{0};  // relaxed as ready_: a count for readers
};

}  // namespace vigil::exporter
