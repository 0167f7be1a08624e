#pragma once
// The ROS 2 output's transport: what `Ros2DiagnosticsOutput` (ros2_diagnostics.cpp, in
// vigil_export) asks of the module that speaks DDS (ros2_transport.cpp, built as the loadable
// module `vigil_ros2` when CMake finds Cyclone DDS).
//
// Why a module: as for HTTP (http_transport.hpp), a program that publishes no ROS 2 diagnostics
// must not map (and, with mlockall, lock) Cyclone DDS. The module is the only object that links
// libddsc and the types idlc generates from src/export/ros2/idl; the output opens it (dlopen)
// when it starts. Both sides are built by the same build with the same compiler and C++ library,
// so C++ types cross the boundary; kRos2TransportAbi and the vigil version guard against a module
// from another build.
#include <cstdint>
#include <string>

#include "vigil/export/diagnostics.hpp"

namespace vigil::exporter::detail {

/// Bumped whenever anything in this header changes.
inline constexpr int kRos2TransportAbi = 2;

/// The module's file name, and the symbols it exports (extern "C").
inline constexpr const char* kRos2ModuleFile = "libvigil_ros2.so";
inline constexpr const char* kRos2ModuleAbiSymbol = "vigil_ros2_transport_abi";
inline constexpr const char* kRos2ModuleVersionSymbol = "vigil_ros2_transport_version";
inline constexpr const char* kRos2ModuleCreateSymbol = "vigil_ros2_transport_create";

struct Ros2TransportConfig {
  std::uint32_t domain_id = 0;
  /// Cyclone DDS configuration (XML, or file URIs, as CYCLONEDDS_URI holds); empty: Cyclone's own
  /// (CYCLONEDDS_URI from the environment, else its defaults).
  std::string config;
  /// The DDS topic ("rt/diagnostics" for the ROS 2 topic /diagnostics).
  std::string topic = "rt/diagnostics";
  /// The ROS 2 node announced on the DDS topic `ros_discovery_info` as the writer's node (checked
  /// by the output: check_ros_node_name, check_ros_namespace); an empty name announces none.
  std::string node_name = "vigil";
  std::string node_namespace = "/";
  /// Bytes of rmw_dds_common/msg/Gid in the robot's ROS 2 distribution: 16 (Iron and later) or
  /// 24 (Foxy to Humble).
  int gid_size = 16;
};

/// What the transport announced on `ros_discovery_info` (empty gids: nothing announced).
struct Ros2NodeAnnouncement {
  std::string participant_gid;  ///< the participant's graph id, `gid_size` bytes
  std::string writer_gid;       ///< the /diagnostics writer's graph id, `gid_size` bytes
};

/// One participant, one topic, one writer of `diagnostic_msgs::msg::dds_::DiagnosticArray_`;
/// and, unless `node_name` is empty, one writer of `ros_discovery_info` that names the ROS 2 node
/// of that writer (written once when the transport is made: transient local, so ROS 2 nodes that
/// start later get it too).
/// publish() from any thread (Cyclone's writer is thread-safe); destroyed on the thread that
/// created it.
class Ros2Transport {
 public:
  virtual ~Ros2Transport() = default;
  /// Writes one sample. Returns "" when written, else why not.
  virtual std::string publish(const DiagnosticArrayMessage& message) = 0;
  /// Readers of the topic matched so far (0 when nobody listens).
  [[nodiscard]] virtual std::uint32_t matched() const = 0;
  /// The node announced (the graph ids it gave), as written to `ros_discovery_info`.
  [[nodiscard]] virtual Ros2NodeAnnouncement node() const = 0;
};

}  // namespace vigil::exporter::detail

extern "C" {
/// kRos2TransportAbi of the module.
using VigilRos2TransportAbiFn = int (*)();
/// The vigil version the module was built from.
using VigilRos2TransportVersionFn = const char* (*)();
/// A new transport (owned by the caller; delete it before closing the module), or null with
/// `*error` saying why (the domain cannot be created, the configuration is bad...).
using VigilRos2TransportCreateFn =
    vigil::exporter::detail::Ros2Transport* (*)(const vigil::exporter::detail::Ros2TransportConfig&,
                                                std::string* error);
}
