// Fuzz target: the rtnetlink RTM_NEWLINK parser of a CAN controller's live state
// (vigil/can/can_link.hpp) on arbitrary bytes: never reads outside them, a refused message says
// why, a parsed one is consistent.
#include <cstddef>
#include <cstdint>
#include <span>

#include "vigil/can/can_link.hpp"

namespace {
void check(bool ok) {
  if (!ok) __builtin_trap();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto info = vigil::can::parse_link_message(std::span<const std::uint8_t>(data, size));
  if (!info) {
    check(!info.error().message.empty());
    return 0;
  }
  check(info->name.size() <= size && info->kind.size() <= size);
  check(!info->state || static_cast<int>(*info->state) <= 5);
  check(info->skipped == 0 || !info->skipped_detail.empty());
  // Only a controller ("can") has CAN attributes and device statistics.
  check(info->kind == "can" || (!info->state && !info->device_stats && !info->bitrate));
  return 0;
}
