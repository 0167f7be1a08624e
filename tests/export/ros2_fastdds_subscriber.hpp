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

class FastDdsDiagnosticsSubscriber {
 public:
  /// A participant in `domain` (UDPv4 on 127.0.0.1 only, 127.0.0.1 as the initial peer) with a
  /// reader of rt/diagnostics with rclcpp's default QoS (reliable, volatile, keep last 10).
  explicit FastDdsDiagnosticsSubscriber(int domain);
  ~FastDdsDiagnosticsSubscriber();
  FastDdsDiagnosticsSubscriber(const FastDdsDiagnosticsSubscriber&) = delete;
  FastDdsDiagnosticsSubscriber& operator=(const FastDdsDiagnosticsSubscriber&) = delete;

  /// Why the reader could not be made; empty when it was.
  [[nodiscard]] const std::string& error() const { return error_; }
  /// The samples received so far, in order.
  [[nodiscard]] std::vector<exporter::DiagnosticArrayMessage> received() const;
  /// The representation identifier of each sample's encapsulation (0x0001: CDR little-endian).
  [[nodiscard]] std::vector<int> encapsulations() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  std::string error_;
};

}  // namespace vigil::test
