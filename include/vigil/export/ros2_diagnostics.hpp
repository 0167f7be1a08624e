#pragma once
/// @file
/// ROS 2's `/diagnostics` without ROS 2: `Ros2DiagnosticsOutput` publishes the monitor's reports
/// as `diagnostic_msgs/msg/DiagnosticArray` directly over DDS (Eclipse Cyclone DDS, the DDS of
/// rmw_cyclonedds_cpp), with ROS 2's conventions, so `ros2 topic echo /diagnostics`, the
/// diagnostic aggregator and rqt_robot_monitor see vigil as they see any ROS 2 node's
/// diagnostics (docs/guide/ros2.md; the conventions and their sources:
/// docs/design/ros2-diagnostics.md):
///
/// | what | value |
/// | --- | --- |
/// | DDS topic | `rt/diagnostics` (the ROS 2 topic `/diagnostics`) |
/// | DDS type | `diagnostic_msgs::msg::dds_::DiagnosticArray_` |
/// | encoding | CDR (XCDR1), as rmw_cyclonedds_cpp writes it |
/// | QoS | reliable, volatile, keep last 10 (rclcpp's default profile) |
/// | domain | `domain_id`, else `ROS_DOMAIN_ID`, else 0 |
/// | ROS 2 node | `/vigil` (`node_namespace`, `node_name`), on the DDS topic `ros_discovery_info` |
///
/// The writer's node: rmw implementations map DDS endpoints to ROS 2 nodes with the samples of the
/// DDS topic `ros_discovery_info` (`rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_`). The
/// output writes one when it starts, naming one node whose one writer is /diagnostics', so
/// `ros2 node list` shows `/vigil` and `ros2 topic info -v /diagnostics` names it as the
/// publisher's node. The layout of that message's graph ids depends on the ROS 2 distribution
/// (`ros_distro`: 24 bytes up to Humble, 16 since Iron).
///
/// What is published: the whole array (one status per report, vigil/export/diagnostics.hpp's
/// mapping) after every monitor cycle, and at once for each event, an array of the one status the
/// event changed (its latest status, raised to the event's severity, the event as its message).
///
/// DDS is in a module (`libvigil_ros2.so`, built when CMake found Cyclone DDS) that the output
/// opens when it starts: a program that publishes nothing to ROS 2 maps no DDS library. Without
/// the module (a build without Cyclone DDS), or with a bad domain id or DDS configuration, the
/// output warns once, naming the setting, and publishes nothing: supervision goes on.
///
/// Threads: as every `Output`; events are published from the output's event subscription (the
/// hub's dispatcher thread). Nothing here is RT-safe, and nothing touches a real-time thread.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/diagnostics.hpp"
#include "vigil/export/output.hpp"

namespace vigil::exporter {

namespace detail {
class Ros2Transport;
}

/// The largest domain id ROS 2 allows (its port mapping: 7400 + 250 * 232 + offsets < 65536).
inline constexpr int kRosDomainIdMax = 232;

/// Checks a domain id written as text (the value of `ROS_DOMAIN_ID`): a decimal integer from 0
/// to kRosDomainIdMax. The error names `what` ("ROS_DOMAIN_ID") and the value. Pure.
[[nodiscard]] expected<int, Error> parse_ros_domain_id(std::string_view text,
                                                       std::string_view what = "ROS_DOMAIN_ID");

/// The domain of the process's `ROS_DOMAIN_ID` (getenv): 0 when unset or empty (as ROS 2), an
/// error naming the variable when it is not a domain id.
[[nodiscard]] expected<int, Error> ros_domain_id_from_environment();

/// The size in bytes of a ROS 2 graph id (rmw_dds_common/msg/Gid) in the distribution `distro`:
/// 24 for foxy, galactic and humble, 16 for iron, jazzy, kilted, lyrical and rolling. Any other
/// name is an error naming `what` and the value. Pure.
[[nodiscard]] expected<int, Error> ros_gid_size(std::string_view distro,
                                                std::string_view what = "ros_distro");

/// Checks a ROS 2 node name as rmw does (rmw_validate_node_name): 1 to 255 of `A-Z a-z 0-9 _`,
/// not starting with a digit. The error names `node_name` and the value. Pure.
[[nodiscard]] expected<void, Error> check_ros_node_name(std::string_view name);

/// Checks a ROS 2 node namespace as rmw does (rmw_validate_namespace): absolute (`/`, `/robot`,
/// `/robot/arm`), tokens of `A-Z a-z 0-9 _` not starting with a digit, no `//`, no trailing `/`
/// (but `/` itself), at most 245 characters. The error names `node_namespace`. Pure.
[[nodiscard]] expected<void, Error> check_ros_namespace(std::string_view ns);

/// Whether this build has the DDS module (CMake found Cyclone DDS): without it a
/// `Ros2DiagnosticsOutput` only warns.
[[nodiscard]] bool ros2_output_built() noexcept;

/// What a `Ros2DiagnosticsOutput` publishes where.
struct Ros2Options {
  /// The DDS domain; none: `ROS_DOMAIN_ID` (read at start), else 0. 0 to kRosDomainIdMax.
  std::optional<int> domain_id{};
  /// Cyclone DDS configuration (XML, or `file://` URIs: what `CYCLONEDDS_URI` holds) for the
  /// output's domain; empty: `CYCLONEDDS_URI`, else Cyclone's defaults. Either comes after
  /// vigil's own fragment (its threads' stack sizes, one receive thread), which it may change.
  /// Used only when no other part of the process created that domain first.
  std::string dds_config{};
  /// Also publish the changed status at once for each event (not only every monitor cycle).
  bool events = true;
  /// Announce the writer's ROS 2 node on `ros_discovery_info` (what `ros2 node list` reads).
  bool node = true;
  /// The node's name (check_ros_node_name); two vigils in one domain need two names.
  std::string node_name = "vigil";
  /// The node's namespace (check_ros_namespace).
  std::string node_namespace = "/";
  /// The ROS 2 distribution of the robot's nodes (ros_gid_size): it fixes the layout of
  /// `ros_discovery_info`. Empty: `ROS_DISTRO` (read at start; a name vigil does not know is a
  /// warning, and Iron's layout is used), else "jazzy".
  std::string ros_distro{};
  /// Unix time in ns stamped in each header; empty: the real-time clock. (A test fixes it.)
  std::function<std::int64_t()> wall_clock_ns{};
  /// Receives every warning as one line without a prefix; empty: "vigil: <line>" on stderr.
  std::function<void(const std::string&)> warn{};
};

/**
 * ROS 2 `/diagnostics` over DDS as an output (see the file comment).
 *
 * **Example**:
 * ```cpp
 * service.add_output(vigil::exporter::make_ros2_output({.domain_id = 7}));
 * ```
 */
class Ros2DiagnosticsOutput final : public Output {
 public:
  explicit Ros2DiagnosticsOutput(Ros2Options options = {});
  ~Ros2DiagnosticsOutput() override;
  Ros2DiagnosticsOutput(const Ros2DiagnosticsOutput&) = delete;
  Ros2DiagnosticsOutput& operator=(const Ros2DiagnosticsOutput&) = delete;

  /// Opens the DDS module and creates the participant and the writer. Never fails: what goes
  /// wrong is a warning (and error()), and the output then publishes nothing.
  expected<void, Error> start(OutputContext& context) override;
  /// The whole array of the cycle.
  void publish(const Snapshot& snapshot) override;
  /// The final array, then the writer and the participant are deleted.
  void stop(const Snapshot& final_snapshot) override;

  /// Whether the writer exists (between a successful start and stop). Any thread.
  [[nodiscard]] bool active() const noexcept { return active_.load(std::memory_order_relaxed); }
  /// Why the output is not active, or the latest failed write; empty when none. Any thread.
  [[nodiscard]] std::string error() const;
  /// The domain the writer is in (valid once started). Any thread.
  [[nodiscard]] int domain_id() const noexcept { return domain_.load(std::memory_order_relaxed); }
  /// Samples written so far (cycles and events). Any thread.
  [[nodiscard]] std::uint64_t published() const noexcept {
    return published_.load(std::memory_order_relaxed);
  }
  /// The fully qualified name of the ROS 2 node announced (`/vigil`), empty when none. Valid once
  /// started. Any thread.
  [[nodiscard]] std::string node() const;
  /// The size of the graph ids announced (16 or 24), 0 when no node was. Any thread.
  [[nodiscard]] int gid_size() const noexcept { return gid_size_.load(std::memory_order_relaxed); }
  /// DDS readers matched now (ROS 2 subscribers of /diagnostics); 0 when not active.
  [[nodiscard]] std::uint32_t matched() const;
  /// Publishes `message` now (what publish() does with its snapshot). False when not active or
  /// the write failed. Any thread.
  bool write(const DiagnosticArrayMessage& message);

 private:
  void fail(const std::string& why);
  void on_event(const Event& e);
  [[nodiscard]] std::int64_t now_ns() const;

  Ros2Options options_;
  mutable std::mutex mutex_;  // guards transport_, error_, latest_
  std::unique_ptr<detail::Ros2Transport> transport_;
  std::string error_;
  std::string node_;               // fully qualified, "" when none announced
  bool write_failed_ = false;      // the latest write failed (said once until one succeeds)
  DiagnosticArrayMessage latest_;  // of the latest cycle: what an event's status starts from
  supervisor::EventHub* hub_ = nullptr;
  std::uint64_t subscription_ = 0;
  // Flags and counts for readers on any thread; relaxed: they order no other data.
  std::atomic<bool> active_{false};
  std::atomic<int> domain_{0};
  std::atomic<int> gid_size_{0};
  std::atomic<std::uint64_t> published_{0};
};

/// A ROS 2 `/diagnostics` output with `options`: the one call a program makes
/// (`service.add_output(make_ros2_output())`).
[[nodiscard]] std::unique_ptr<Ros2DiagnosticsOutput> make_ros2_output(Ros2Options options = {});

}  // namespace vigil::exporter
