#pragma once
/// @file
/// The `can:` section of a deployment (target `vigil::deploy_can`): CAN supervision that lives
/// with a `System`. The section is a CAN configuration (docs/reference/can-config.md); the
/// extension owns a CAN registry for the sniffers of the deployment's CAN I/O components, a CAN
/// supervisor thread (10 Hz) and a CAN monitor whose verdicts join the system's reports: one
/// report per node ("can0/drive_5", kind CanNode), one per group ("can group left_arm"), and one
/// for the CAN supervisor itself ("vigil.can-supervisor", kind Supervisor). Node silences are
/// judged up to the time the CAN supervisor read the sniffers, so a late CAN supervisor turns no
/// node ERROR; its delay is its own report's finding (Stale beyond
/// `CanMonitorOptions::stale_after_ns`, 1 s).
///
/// Linking `vigil::deploy_can` (or the umbrella `vigil::vigil`) registers the extension before
/// `main` runs, so any program that loads a deployment with a `can:` section gets CAN
/// supervision; `register_can_extension()` does the same explicitly (idempotent). A CAN I/O
/// component finds the extension through its context:
///
/// ```cpp
/// auto* can = ctx.system->extension<vigil::deploy::CanExtension>();
/// sniffer_ = std::make_unique<vigil::can::Sniffer<256>>(can->registry(), ctx.name, options);
/// static_cast<void>(sniffer_->set_filter(can->config().filter));
/// ```
///
/// Threads: the System's control thread calls start/stopping/stop; `contribute` runs on the
/// threads that read the System's reports. Not RT-safe (only the sniffers are).

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/can_config.hpp"
#include "vigil/can/can_link.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/can/can_statistics.hpp"
#include "vigil/can/sniffer.hpp"
#include "vigil/deploy/extension.hpp"
#include "vigil/supervisor/events.hpp"

namespace vigil::deploy {

/// The name of the deployment section the CAN extension handles.
inline constexpr std::string_view kCanSection = "can";
/// The name of the CAN supervisor's report.
inline constexpr std::string_view kCanSupervisorName = "vigil.can-supervisor";

/// CAN supervision configured by a deployment's `can:` section.
class CanExtension : public Extension {
 public:
  /// Builds the registry, aggregator, supervisor (not started) and monitor for `config`. With
  /// `events`, a node that stops responding and one that responds again are published there
  /// (`EventKind::NotResponding`, `EventKind::Responding`), once per change, and what the frames
  /// say (CANopen NMT states, resets, emergencies and NMT commands; controller error warning,
  /// error passive, bus off and back to error active; J1939 trouble codes; DroneCAN health)
  /// once each, with the frame's time. They leave at the CAN supervisor's pace, not the
  /// monitor's: at the end of each of its drains the CAN supervisor's thread judges the nodes
  /// (`CanMonitor::evaluate`, up to the time it read the sniffers) and publishes what changed,
  /// and it wakes for one more drain when the earliest silence limit of a responding node
  /// passes, so a silent node is an event within milliseconds of its limit.
  explicit CanExtension(can::CanConfig config, supervisor::EventHub* events = nullptr);
  /// Stops the CAN supervisor (as stop()) if it still runs.
  ~CanExtension() override;
  CanExtension(const CanExtension&) = delete;
  CanExtension& operator=(const CanExtension&) = delete;
  /// Starts the CAN supervisor thread; fails when the thread cannot be created.
  expected<void, Error> start() override;
  /// Records the moment the system began to stop: liveness is judged as of then afterwards.
  void stopping() override;
  /// Stops the CAN supervisor after a last drain.
  void stop() override;
  /// Adds one report per CAN node, one per group, one per bus and the CAN supervisor's to the
  /// cycle's reports, and the gap buckets of every node (rx and tx) and group from the CAN
  /// aggregator's histograms (its samples in exact mode), taken right after the reports. Once
  /// per monitor cycle. First it reads the controller state of every bus that names its
  /// SocketCAN interface (`buses.<bus>.interface`) through netlink: a state change is an event
  /// (error warning, error passive, bus off, error active), the bitrate is the bus's when the
  /// configuration gives none, and an interface that cannot be read (none, not a CAN device)
  /// is its bus's WARN with the reason; supervision goes on.
  void contribute(exporter::Snapshot& snapshot) override;
  /// Its configured nodes on a bus ("can0/drive_5") and its groups ("can group right_arm").
  [[nodiscard]] std::vector<std::string> unit_names() const override;

  /// Where the deployment's sniffers join. Thread-safe.
  [[nodiscard]] can::CanRegistry& registry() noexcept { return registry_; }
  /// The section as loaded (filter, node map, thresholds, nodes, groups).
  [[nodiscard]] const can::CanConfig& config() const noexcept { return config_; }
  /// The CAN monitor (e.g. to add checks or replace the configuration). Thread-safe. Checks
  /// added here run on the CAN supervisor's thread at each drain (the events) as well as on the
  /// monitor's (the reports): keep them quick and thread-safe.
  [[nodiscard]] can::CanMonitor& monitor() noexcept { return *monitor_; }

  /// How a bus's interface is read: `can::query_link` (rtnetlink) unless replaced here, e.g. by
  /// recorded answers in a test or on a machine without SocketCAN. Thread-safe.
  using LinkQuery = std::function<expected<can::LinkInfo, Error>(std::string_view interface)>;
  void set_link_query(LinkQuery query);

 private:
  can::CanConfig config_;
  can::CanRegistry registry_;
  std::unique_ptr<can::CanAggregator> statistics_;
  std::unique_ptr<can::CanDrainLoop> supervisor_;
  // Held while the supervisor's thread starts or stops and while a report steps it by hand (the
  // monitor's thread, when the supervisor's own thread does not run): never two steps at once.
  std::mutex step_mutex_;
  std::unique_ptr<can::CanMonitor> monitor_;
  void add_reports(ReportSet& reports, std::vector<exporter::CanHistograms>* histograms,
                   std::vector<exporter::CanBusLoads>* buses = nullptr);
  // The CAN supervisor's cycle hook (its thread, or the caller of a manual step): judges the
  // nodes, publishes what changed and asks for a wake-up at the next silence limit.
  void on_can_cycle(const supervisor::DrainCycle& c);
  void schedule_wake(const can::CanReport& r);
  // How close before the next regular drain a limit may pass without a drain of its own.
  static Nanos wake_margin(Nanos period) noexcept;
  Nanos regular_next_ = 0;               // the next regular drain (cycle hook only)
  std::atomic<Nanos> judge_last_ns_{0};  // the cycle hook's latest and longest time
  std::atomic<Nanos> judge_max_ns_{0};
  void publish_changes(const can::CanReport& r, Nanos now);
  void publish_protocol_events(const can::CanReport& r);
  [[nodiscard]] Report supervisor_report(const can::CanReport& r, bool running) const;

  // The buses' interfaces read through netlink (`buses.<bus>.interface`), at the monitor's
  // pace (add_reports), never on a sniffer's thread.
  void read_links();
  std::mutex links_mutex_;  // guards links_ and link_bitrates_ (the monitor's thread, step_monitor)
  std::vector<can::LinkReading> links_;
  LinkQuery link_query_;  // null: can::query_link
  std::vector<std::pair<std::uint8_t, std::pair<std::uint32_t, std::uint32_t>>> link_bitrates_;

  std::atomic<Nanos> stopped_at_{0};  // once stopping: the time liveness is judged at
  supervisor::EventHub* events_ = nullptr;
  // The nodes not responding at the latest evaluation, by report name (the CAN supervisor's
  // cycle hook: its thread, or a caller stepping it under step_mutex_; never two at once).
  std::map<std::string, bool> not_responding_;
  // The latest protocol event published (`CanAggregator::protocol_events_after`).
  std::uint64_t protocol_seq_ = 0;
};

/// Registers the extension for the `can:` section (idempotent, thread-safe). Linking
/// `vigil::deploy_can` already does it at static initialisation.
void register_can_extension();

}  // namespace vigil::deploy
