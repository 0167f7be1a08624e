#include "deploy/bytes.hpp"

#include <fmt/format.h>

#include <array>
#include <cctype>
#include <cstdint>
#include <limits>

namespace vigil::deploy::detail {

namespace {

struct Unit {
  std::string_view name;
  std::uint64_t bytes;
};
constexpr std::array<Unit, 4> kUnits{{{"B", 1},
                                      {"KiB", 1024},
                                      {"MiB", std::uint64_t{1024} * 1024},
                                      {"GiB", std::uint64_t{1024} * 1024 * 1024}}};

/// The binary unit a decimal-looking one was probably meant as, or "".
std::string_view hint_for(std::string_view unit) {
  if (unit == "K" || unit == "k" || unit == "KB" || unit == "kB" || unit == "kb" || unit == "Kb" ||
      unit == "kiB" || unit == "kib" || unit == "KIB") {
    return "KiB";
  }
  if (unit == "M" || unit == "m" || unit == "MB" || unit == "mB" || unit == "mb" || unit == "MIB" ||
      unit == "mib") {
    return "MiB";
  }
  if (unit == "G" || unit == "g" || unit == "GB" || unit == "gb" || unit == "GIB" ||
      unit == "gib") {
    return "GiB";
  }
  if (unit == "b" || unit == "bytes" || unit == "byte") return "B";
  return "";
}

constexpr std::size_t kMinStack = std::size_t{16} * 1024;
constexpr std::size_t kMaxStack = std::size_t{1024} * 1024 * 1024;

}  // namespace

expected<std::size_t, std::string> parse_bytes(std::string_view text) {
  const std::string quoted = fmt::format("'{}'", text);
  std::size_t i = 0;
  while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
  if (i < text.size() && text[i] == '+') ++i;
  // Digits with at most one '.', read exactly as a fraction whole / 10^decimals.
  std::uint64_t whole = 0;
  std::uint64_t scale = 1;
  bool digits = false;
  bool dot = false;
  for (; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '.' && !dot) {
      dot = true;
      continue;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) == 0) break;
    digits = true;
    if (whole > (std::numeric_limits<std::uint64_t>::max() - 9) / 10 ||
        (dot && scale > std::numeric_limits<std::uint64_t>::max() / 10)) {
      return unexpected(fmt::format("{} is too large", quoted));
    }
    whole = whole * 10 + static_cast<std::uint64_t>(c - '0');
    if (dot) scale *= 10;
  }
  if (!digits) {
    return unexpected(
        fmt::format("{} is not a size: write a number and a unit (B, KiB, MiB, GiB), "
                    "e.g. 512KiB",
                    quoted));
  }
  while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
  std::string_view unit = text.substr(i);
  while (!unit.empty() && (unit.back() == ' ' || unit.back() == '\t')) unit.remove_suffix(1);
  if (unit.empty()) {
    return unexpected(
        fmt::format("{} has no unit: write it with B, KiB, MiB or GiB (e.g. {}B or "
                    "64KiB)",
                    quoted, text));
  }
  const Unit* u = nullptr;
  for (const auto& k : kUnits) {
    if (k.name == unit) u = &k;
  }
  if (u == nullptr) {
    const std::string_view hint = hint_for(unit);
    if (!hint.empty()) {
      return unexpected(
          fmt::format("{}: unknown unit '{}'; did you mean '{}' (sizes use binary "
                      "units: 1KiB = 1024 bytes)?",
                      quoted, unit, hint));
    }
    return unexpected(fmt::format("{}: unknown unit '{}' (known: B, KiB, MiB, GiB)", quoted, unit));
  }
  if (whole != 0 && u->bytes > std::numeric_limits<std::uint64_t>::max() / whole) {
    return unexpected(fmt::format("{} is too large", quoted));
  }
  const std::uint64_t scaled = whole * u->bytes;
  if (scaled % scale != 0) {
    return unexpected(fmt::format("{} is not a whole number of bytes", quoted));
  }
  const std::uint64_t bytes = scaled / scale;
  if (bytes > std::numeric_limits<std::size_t>::max()) {
    return unexpected(fmt::format("{} is too large", quoted));
  }
  return static_cast<std::size_t>(bytes);
}

std::string format_bytes(std::size_t bytes) {
  for (auto it = kUnits.rbegin(); it != kUnits.rend(); ++it) {
    if (bytes >= it->bytes && bytes % it->bytes == 0) {
      return fmt::format("{}{}", bytes / it->bytes, it->name);
    }
  }
  return fmt::format("{}B", bytes);
}

std::size_t optional_stack(const config::Node& parent, std::string_view key, std::size_t fallback) {
  const config::Node n = parent[key];
  if (!n.defined()) return fallback;
  if (n.is_null() || !n.is_scalar()) {
    (void)n.get<std::string>();  // reports "got an empty value", "expected a scalar"...
    return fallback;
  }
  const std::string text = n.get<std::string>();
  if (text == "system") return 0;
  auto bytes = parse_bytes(text);
  if (!bytes) {
    n.error(bytes.error());
    return fallback;
  }
  if (*bytes < kMinStack || *bytes > kMaxStack) {
    n.error(fmt::format("a thread stack must be between {} and {} (or 'system'), got '{}'",
                        format_bytes(kMinStack), format_bytes(kMaxStack), text));
    return fallback;
  }
  return *bytes;
}

}  // namespace vigil::deploy::detail
