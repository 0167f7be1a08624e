#pragma once
/// @file
/// `Monitor`: runs the checks on every supervised component each cycle and publishes one
/// `Report` per component, plus one for the supervisor ("vigil.supervisor") and one for itself
/// ("vigil.monitor").
///
/// Design: a non-RT thread of its own (`start()`/`stop()`, SCHED_OTHER), or `step()` called from
/// a loop you own. A cycle: (1) runs the cycle hooks (e.g. a `ThresholdFile` polling its file,
/// vigil/monitor/threshold_file.hpp); (2) copies the aggregator's snapshots; (3) per component,
/// computes the recent window from the counters it kept at earlier cycles, the silence since the
/// latest cycle, the tasks sharing its thread and the thread's OS counters, and runs the checks;
/// (4) publishes the ReportSet under a mutex held only for the swap, then calls the subscribers.
/// The monitor never touches the RT side: it reads the aggregator (which the supervisor fills) and
/// the thresholds it is given, nothing else; it reads no file.
///
/// Thread safety: every member is thread-safe; `step()` calls are serialised with each other and
/// with the thread's cycles. Nothing here is RT-safe.

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "vigil/config/error.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/check.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/monitor/thresholds.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::monitor {

/// Options of a monitor.
struct MonitorOptions {
  /// Period of the monitor's own thread. 1 s: the pace of a monitoring GUI (ROS diagnostics
  /// publishes at 1 Hz).
  Nanos period_ns = kNanosPerSecond;
  std::string thread_name = "vigil-monitor";
  /// Stack of the monitor's thread, in bytes (0: the system default, usually 8 MiB). Custom
  /// checks run on it.
  std::size_t stack_bytes = platform::kDefaultStackBytes;
  /// The monitor's clock (cycle times, silences, windows). It must be the aggregator's clock
  /// (AggregatorOptions::clock): silences compare it with the aggregator's arrival stamps.
  Clock clock = Clock::system();
  /// Run the built-in checks (checks::add_builtin_checks) before the custom ones.
  bool builtin_checks = true;
  /// Read each component thread's OS counters (platform::read_thread_stats, ~6 us per thread).
  bool read_thread_stats = true;
  /// Add the "vigil.monitor" report (the monitor's own cycles, and threshold reload errors).
  bool self_report = true;
  std::string supervisor_name = "vigil.supervisor";
  std::string monitor_name = "vigil.monitor";
};

class Monitor {
 public:
  /// A subscriber, called after each cycle on the monitor's thread (or step()'s caller).
  using Callback = std::function<void(const ReportSet&)>;

  /// Monitors the components of `aggregator`, which must outlive the monitor. Not RT-safe.
  explicit Monitor(const supervisor::ComponentAggregator& aggregator, MonitorOptions options = {});
  /// Stops the thread if it runs.
  ~Monitor();
  Monitor(const Monitor&) = delete;
  Monitor& operator=(const Monitor&) = delete;

  /// Also reports `supervisor` (which must outlive the monitor, or be detached with nullptr):
  /// its cycles, drain time, messages and ports, Stale when it stopped cycling and Warn when its
  /// drain time nears its period.
  void set_supervisor(const supervisor::ComponentDrainLoop* supervisor);

  // --- checks ---

  /// Appends a custom check of type `C` built from `args`; it runs after the built-in ones on
  /// every component. Returns the check (owned by the monitor; do not touch it while the
  /// monitor runs). Example: `monitor.add_check<LatencyCheck>();`.
  template <Check C, class... A>
  C& add_check(A&&... args) {
    auto lock = lock_checks_();
    return checks_().template add<C>(std::forward<A>(args)...);
  }
  /// Appends `check`. Example: `monitor.add_check(LatencyCheck{200});`.
  template <Check C>
  C& add_check(C check) {
    auto lock = lock_checks_();
    return checks_().add(std::move(check));
  }
  /// Removes the checks named `name` (built-in ones included); returns how many.
  std::size_t remove_check(std::string_view name);
  /// Names of the checks, in the order they run.
  [[nodiscard]] std::vector<std::string> check_names() const;

  // --- thresholds ---

  /// Replaces the thresholds (taken as they are: validate them by loading YAML) and clears the
  /// reported threshold errors. Takes effect at the next cycle. The "vigil.monitor" report shows
  /// generation 0 for thresholds set this way.
  void set_thresholds(ThresholdSet thresholds);
  /// Same, sharing an existing value (null is ignored), with the `generation` the
  /// "vigil.monitor" report shows (a file's reload count, see ThresholdFile).
  void set_thresholds(std::shared_ptr<const ThresholdSet> thresholds, std::uint64_t generation);
  /// The thresholds in use (never null; the built-in defaults until set).
  [[nodiscard]] std::shared_ptr<const ThresholdSet> thresholds() const;
  /// The generation given with the thresholds in use (0 when set without one).
  [[nodiscard]] std::uint64_t thresholds_generation() const;
  /// Reports `errors` (a failed reload of the thresholds' source; the thresholds in use are
  /// kept) as WARN messages of the "vigil.monitor" report until the next `set_thresholds` or
  /// `set_threshold_errors({})`.
  void set_threshold_errors(config::ConfigErrors errors);
  /// The errors reported with `set_threshold_errors` and not cleared since.
  [[nodiscard]] config::ConfigErrors threshold_errors() const;

  // --- cycle hooks ---

  /// A hook, called at the start of every cycle on the monitor's thread (or step()'s caller),
  /// before the thresholds are read: a `ThresholdFile` polls its file there.
  using CycleHook = std::function<void()>;
  /// Adds a hook; returns its id. Waits for a cycle under way. A hook must not call step(),
  /// stop(), add/remove_cycle_hook or the destructor; exceptions it throws are ignored.
  std::uint64_t add_cycle_hook(CycleHook hook);
  /// Removes a hook (unknown ids are ignored); once it returns, the hook is not running and will
  /// not run again. Waits for a cycle under way.
  void remove_cycle_hook(std::uint64_t id);

  // --- running ---

  /// Runs one cycle in the calling thread and returns its reports. Serialised with the thread's
  /// cycles (safe to call while the monitor runs).
  ReportSet step();
  /// Starts the monitor's thread (SCHED_OTHER), which runs a cycle every period, the first one
  /// period after the start (not at once: nothing has configured yet). Fails when the thread
  /// cannot be created. Idempotent.
  expected<void, Error> start();
  /// Stops and joins the thread (wakes it at once). Idempotent.
  void stop();
  [[nodiscard]] bool running() const noexcept;

  // --- readers ---

  /// A copy of the latest cycle's reports (empty before the first cycle). Any thread.
  [[nodiscard]] ReportSet latest() const;
  /// A copy of the latest cycle's component reports. Any thread.
  [[nodiscard]] std::vector<Report> reports() const;
  /// Adds a subscriber called after every cycle with its reports; returns its id. It must not
  /// call step(), stop() or the destructor (they wait for the cycle that calls it).
  std::uint64_t subscribe(Callback callback);
  /// Removes a subscriber; unknown ids are ignored.
  void unsubscribe(std::uint64_t id);

  [[nodiscard]] const MonitorOptions& options() const noexcept;

  struct Impl;

 private:
  [[nodiscard]] std::unique_lock<std::mutex> lock_checks_() const;
  [[nodiscard]] CheckList& checks_() noexcept;

  std::unique_ptr<Impl> impl_;
};

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::Monitor;
using monitor::MonitorOptions;
}  // namespace vigil
