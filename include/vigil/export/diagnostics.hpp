#pragma once
/// @file
/// The monitor's reports as a ROS 2 `diagnostic_msgs/msg/DiagnosticArray` in JSON, the shape a
/// ROS bridge or an rqt_robot_monitor-style tool takes as it is:
///
/// ```json
/// {"header": {"stamp": {"sec": 1700000000, "nanosec": 250000000}, "frame_id": ""},
///  "status": [{"level": 2, "name": "vigil: encoder", "message": "exception: ...",
///              "hardware_id": "tid 4242 cpu 0",
///              "values": [{"key": "state", "value": "Exception"}, ...]}]}
/// ```
///
/// Mapping: `level` is the status as an integer (OK 0, WARN 1, ERROR 2, STALE 3: the values of
/// DiagnosticStatus' constants); `name` is "vigil: <report name>"; `message` the findings joined
/// by "; " ("OK" when there is none); `hardware_id` the thread and CPU for components
/// ("tid 4242 cpu 1", "cpu any" when not pinned, "" before the thread is known), "bus:node" for
/// CAN nodes ("can0:drive_5"), "can:<group>" for CAN groups, "vigil" for the supervisor and the
/// monitor; `values` are string key/value pairs: the main figures, then the checks' values.
/// docs/reference/http.md lists the keys.
///
/// Not RT-safe (allocates); any thread; pure.

#include <cstdint>
#include <string>
#include <vector>

#include "vigil/monitor/report.hpp"

namespace vigil::exporter {

/// `diagnostic_msgs/msg/KeyValue`.
struct DiagnosticKeyValue {
  std::string key{};
  std::string value{};
  bool operator==(const DiagnosticKeyValue&) const = default;
};

/// `diagnostic_msgs/msg/DiagnosticStatus`.
struct DiagnosticStatusMessage {
  std::uint8_t level = 0;  ///< OK 0, WARN 1, ERROR 2, STALE 3
  std::string name{};
  std::string message{};
  std::string hardware_id{};
  std::vector<DiagnosticKeyValue> values{};
  bool operator==(const DiagnosticStatusMessage&) const = default;
};

/// `diagnostic_msgs/msg/DiagnosticArray`: its header (`std_msgs/msg/Header`: a
/// `builtin_interfaces/msg/Time` stamp and a frame id) and its statuses. The one value both the
/// JSON document and the ROS 2 output (vigil/export/ros2_diagnostics.hpp) are made from.
struct DiagnosticArrayMessage {
  std::int32_t sec = 0;       ///< header.stamp.sec
  std::uint32_t nanosec = 0;  ///< header.stamp.nanosec
  std::string frame_id{};     ///< header.frame_id ("" from vigil)
  std::vector<DiagnosticStatusMessage> status{};
  /// Not in the ROS 2 message: the names of the statuses that are root causes (the diagnosis
  /// graph's; vigil/monitor/diagnosis.hpp), in the JSON document only.
  std::vector<std::string> root_causes{};
  bool operator==(const DiagnosticArrayMessage&) const = default;
};

/// The status of one report (see the file comment for the mapping).
[[nodiscard]] DiagnosticStatusMessage to_diagnostic_status(const Report& report);

/// The DiagnosticArray of `reports`, stamped `wall_time_ns` (Unix time in ns; the seconds are
/// clamped to the range of `sec`).
[[nodiscard]] DiagnosticArrayMessage to_diagnostic_array(const ReportSet& reports,
                                                         std::int64_t wall_time_ns);

/// `message` as JSON (the document of the file comment). `indent` as `JsonWriter` (0: one line).
[[nodiscard]] std::string to_diagnostics_json(const DiagnosticArrayMessage& message,
                                              int indent = 0);

/// The DiagnosticArray of `reports`, stamped `wall_time_ns` (Unix time in ns). `indent` as
/// `JsonWriter` (0: one line).
[[nodiscard]] std::string to_diagnostics_json(const ReportSet& reports, std::int64_t wall_time_ns,
                                              int indent = 0);

/// The `hardware_id` of `report` (see the file comment).
[[nodiscard]] std::string hardware_id(const Report& report);

}  // namespace vigil::exporter
