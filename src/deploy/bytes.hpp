#pragma once
// Private to the deploy module: sizes in bytes written with a unit (`512KiB`, `1 MiB`), for the
// stack keys of a deployment.
#include <cstddef>
#include <string>
#include <string_view>

#include "vigil/config/node.hpp"
#include "vigil/expected.hpp"

namespace vigil::deploy::detail {

/// Parses `text`: a whole or decimal number, optional spaces, then `B`, `KiB`, `MiB` or `GiB`
/// (binary units; `KB`, `kB`, `K`, `MB`... are refused with a hint, since they are ambiguous).
/// A bare number is an error (the unit must be written). The result must be a whole number of
/// bytes. Not RT-safe.
[[nodiscard]] expected<std::size_t, std::string> parse_bytes(std::string_view text);

/// Formats `bytes` with the largest binary unit that keeps it whole: 524288 -> "512KiB".
[[nodiscard]] std::string format_bytes(std::size_t bytes);

/// Reads the thread stack size at `parent[key]`: a size (`512KiB`) between 16KiB and 1GiB, or
/// `system` (0: the system's default stack, `ulimit -s`). Absent: `fallback`. Errors are recorded
/// at the value (file:line:col) and `fallback` is returned.
[[nodiscard]] std::size_t optional_stack(const config::Node& parent, std::string_view key,
                                         std::size_t fallback);

}  // namespace vigil::deploy::detail
