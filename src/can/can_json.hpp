#pragma once
// Private to the can module: the CAN report's JSON members, written into a caller's object so
// that `can-stats` can add its own members around them.

#include <string>
#include <vector>

#include "vigil/can/can_monitor.hpp"
#include "vigil/export/json_writer.hpp"

namespace vigil::can::detail {

/// Writes the members of the report (status, totals, summary, nodes, ids, sniffers) into the
/// object `w` has open.
void write_report_members(JsonWriter& w, const CanReport& report,
                          const std::vector<std::string>& bus_names);

/// "0CF00400" (extended, 8 digits) or "181" (standard, 3 digits), as candump writes ids.
[[nodiscard]] std::string format_id(std::uint32_t id, bool extended);

/// Bus `bus` for people: `bus_names[bus]` when there is one, else the number.
[[nodiscard]] std::string bus_name(std::uint8_t bus, const std::vector<std::string>& bus_names);

}  // namespace vigil::can::detail
