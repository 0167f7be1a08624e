#pragma once
// A ROS 2 /diagnostics subscriber on eProsima Fast DDS (Debian libfastrtps-dev 2.9, the DDS of
// rmw_fastrtps_cpp, ROS 2 Jazzy's default middleware): another vendor, so what it receives came
// over the wire (RTPS on UDP, loopback only). Its type support is written by hand (Debian ships
// no fastddsgen): `diagnostic_msgs::msg::dds_::DiagnosticArray_` in CDR, field by field.
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vigil/export/diagnostics.hpp"

namespace vigil::test {

/// One node of a `ros_discovery_info` sample (rmw_dds_common/msg/NodeEntitiesInfo); graph ids as
/// their bytes.
struct RosNodeInfo {
  std::string node_namespace;
  std::string node_name;
  std::vector<std::string> readers;
  std::vector<std::string> writers;
};

/// A `ros_discovery_info` sample (rmw_dds_common/msg/ParticipantEntitiesInfo).
struct RosParticipantInfo {
  std::string gid;
  std::vector<RosNodeInfo> nodes;
};

class FastDdsDiagnosticsSubscriber {
 public:
  /// A participant in `domain` (UDPv4 on 127.0.0.1 only, 127.0.0.1 as the initial peer) with a
  /// reader of rt/diagnostics with rclcpp's default QoS (reliable, volatile, keep last 10); with
  /// `gid_size` (16: Iron and later, 24: Humble), also a reader of `ros_discovery_info` as
  /// rmw_fastrtps_cpp makes it (reliable, transient local, keep all), its type written by hand.
  explicit FastDdsDiagnosticsSubscriber(int domain, int gid_size = 0);
  ~FastDdsDiagnosticsSubscriber();
  FastDdsDiagnosticsSubscriber(const FastDdsDiagnosticsSubscriber&) = delete;
  FastDdsDiagnosticsSubscriber& operator=(const FastDdsDiagnosticsSubscriber&) = delete;

  /// Why the reader could not be made; empty when it was.
  [[nodiscard]] const std::string& error() const { return error_; }
  /// The samples received so far, in order.
  [[nodiscard]] std::vector<exporter::DiagnosticArrayMessage> received() const;
  /// The representation identifier of each sample's encapsulation (0x0001: CDR little-endian).
  [[nodiscard]] std::vector<int> encapsulations() const;
  /// The `ros_discovery_info` samples received so far.
  [[nodiscard]] std::vector<RosParticipantInfo> discovery() const;
  /// The graph id of the writer of the latest /diagnostics sample, as rmw_fastrtps_cpp gives a
  /// message's publisher_gid: the writer's GUID from the sample's identity (its 12-byte prefix,
  /// then its 4-byte entity id), zeros up to `gid_size`. Empty before the first sample.
  [[nodiscard]] std::string writer_gid() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  std::string error_;
};

}  // namespace vigil::test
