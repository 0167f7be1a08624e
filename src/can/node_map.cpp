#include "vigil/can/node_map.hpp"

#include <fmt/format.h>

#include <array>

namespace vigil::can {

std::string format_node(NodeMapKind kind, std::uint32_t node) {
  switch (kind) {
    case NodeMapKind::CanOpen:
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
    case NodeMapKind::CanOpen: {
      // CiA 301 pre-defined connection set: the function code is the id's top 4 bits.
      static constexpr std::array<const char*, 16> kNames{
          "NMT",   "SYNC/EMCY", "TIME",  "TPDO1", "RPDO1",
          "TPDO2", "RPDO2",     "TPDO3", "RPDO3", "TPDO4",
          "RPDO4", "TSDO",      "RSDO",  "0xD",   "NMT error control",
          "LSS"};
      if (function < kNames.size()) return kNames[function];
      return fmt::format("0x{:X}", function);
    }
    case NodeMapKind::J1939:
      return fmt::format("PGN {} (0x{:04X})", function, function);
    case NodeMapKind::User:
      break;
  }
  return fmt::format("0x{:X}", function);
}

}  // namespace vigil::can
