#include "vigil/can/node_map.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <utility>

namespace vigil::can {

namespace {

using NamedType = std::pair<std::uint16_t, const char*>;

// DroneCAN's standard data types (DSDL namespace uavcan), by ID: messages and services.
constexpr std::array<NamedType, 27> kDroneCanMessages{{
    {1, "dynamic_node_id.Allocation"},
    {4, "GlobalTimeSync"},
    {5, "Panic"},
    {341, "NodeStatus"},
    {380, "enumeration.Indication"},
    {390, "dynamic_node_id.server.Discovery"},
    {1000, "ahrs.Solution"},
    {1001, "ahrs.MagneticFieldStrength"},
    {1002, "ahrs.MagneticFieldStrength2"},
    {1003, "ahrs.RawIMU"},
    {1010, "actuator.ArrayCommand"},
    {1011, "actuator.Status"},
    {1028, "air_data.StaticPressure"},
    {1029, "air_data.StaticTemperature"},
    {1030, "esc.RawCommand"},
    {1031, "esc.RPMCommand"},
    {1034, "esc.Status"},
    {1060, "gnss.Fix"},
    {1061, "gnss.Auxiliary"},
    {1063, "gnss.Fix2"},
    {1090, "power.PrimaryPowerSupplyStatus"},
    {1092, "power.BatteryInfo"},
    {1100, "safety.ArmingStatus"},
    {1110, "device.Temperature"},
    {2000, "navigation.GlobalNavigationSolution"},
    {16370, "debug.KeyValue"},
    {16383, "debug.LogMessage"},
}};
constexpr std::array<NamedType, 13> kDroneCanServices{{
    {1, "GetNodeInfo"},
    {2, "GetDataTypeInfo"},
    {4, "GetTransportStats"},
    {5, "RestartNode"},
    {6, "AccessCommandShell"},
    {10, "param.ExecuteOpcode"},
    {11, "param.GetSet"},
    {40, "file.BeginFirmwareUpdate"},
    {45, "file.GetInfo"},
    {46, "file.GetDirectoryEntryInfo"},
    {47, "file.Delete"},
    {48, "file.Read"},
    {49, "file.Write"},
}};

template <std::size_t N>
const char* name_of(const std::array<NamedType, N>& table, std::uint32_t id) {
  const auto it =
      std::find_if(table.begin(), table.end(), [&](const NamedType& t) { return t.first == id; });
  return it == table.end() ? nullptr : it->second;
}

std::string canopen_function(std::uint32_t function) {
  using namespace canopen;
  switch (function) {
    case kNmt:
      return "NMT";
    case kEmcy:
      return "EMCY";
    case kTime:
      return "TIME";
    case kTpdo1:
      return "TPDO1";
    case kRpdo1:
      return "RPDO1";
    case kTpdo2:
      return "TPDO2";
    case kRpdo2:
      return "RPDO2";
    case kTpdo3:
      return "TPDO3";
    case kRpdo3:
      return "RPDO3";
    case kTpdo4:
      return "TPDO4";
    case kRpdo4:
      return "RPDO4";
    case kSdoTx:
      return "SDO response";
    case kSdoRx:
      return "SDO request";
    case kErrorControl:
      return "NMT error control";
    case kSync:
      return "SYNC";
    case kLssResponse:
      return "LSS response";
    case kLssRequest:
      return "LSS request";
    case kOther:
      return "other";
    default:
      return fmt::format("0x{:X}", function);
  }
}

std::string dronecan_function(std::uint32_t function) {
  if (function == dronecan::kOther) return "other";
  if ((function & dronecan::kService) != 0) {
    const std::uint32_t id = function & 0xFF;
    const char* name = name_of(kDroneCanServices, id);
    return name != nullptr ? fmt::format("service {} {}", id, name) : fmt::format("service {}", id);
  }
  if ((function & dronecan::kAnonymous) != 0) {
    return fmt::format("anonymous message (type ID bits {})", function & 0x3);
  }
  const std::uint32_t id = function & 0xFFFF;
  const char* name = name_of(kDroneCanMessages, id);
  return name != nullptr ? fmt::format("{} {}", id, name) : fmt::format("message {}", id);
}

}  // namespace

std::string format_node(NodeMapKind kind, std::uint32_t node) {
  if (node == kNoNode) return "-";
  switch (kind) {
    case NodeMapKind::CanOpen:
    case NodeMapKind::DroneCan:
      return fmt::format("{}", node);
    case NodeMapKind::J1939:
      return fmt::format("0x{:02X}", node);
    case NodeMapKind::Identity:
    case NodeMapKind::User:
      break;
  }
  return fmt::format("0x{:X}", node);
}

std::string format_function(NodeMapKind kind, std::uint32_t function) {
  switch (kind) {
    case NodeMapKind::Identity:
      return "-";
    case NodeMapKind::CanOpen:
      return canopen_function(function);
    case NodeMapKind::J1939:
      return fmt::format("PGN {} (0x{:04X})", function, function);
    case NodeMapKind::DroneCan:
      return dronecan_function(function);
    case NodeMapKind::User:
      break;
  }
  return fmt::format("0x{:X}", function);
}

}  // namespace vigil::can
