#pragma once
// Formatting shared by the built-in checks (private to src/monitor).

#include <fmt/format.h>

#include <string>

namespace vigil::monitor::checks::detail {

/// A ratio as a percentage with up to 3 significant digits: "93%", "0.1%", "12.5%".
inline std::string percent(double ratio) {
  const double p = ratio * 100.0;
  if (p == 0.0) return "0%";
  if (p < 1.0) return fmt::format("{:.2g}%", p);
  if (p < 10.0) return fmt::format("{:.1f}%", p);
  return fmt::format("{:.0f}%", p);
}

}  // namespace vigil::monitor::checks::detail
