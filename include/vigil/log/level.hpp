#pragma once
/// @file
/// Log levels, and `VIGIL_LOG_LEVEL`, the compile-time filter.
///
/// A level is filtered twice: at compile time, calls below `VIGIL_LOG_LEVEL` compile to nothing
/// (their arguments are not evaluated; their format string is still checked); at run time, each
/// component has its own level (Info by default), reloadable from any thread (see source.hpp).

#include <cstdint>
#include <optional>
#include <string_view>

/// The numeric levels, for `VIGIL_LOG_LEVEL` (a macro: `-DVIGIL_LOG_LEVEL=VIGIL_LOG_LEVEL_WARN`).
#define VIGIL_LOG_LEVEL_DEBUG 0
#define VIGIL_LOG_LEVEL_INFO 1
#define VIGIL_LOG_LEVEL_WARN 2
#define VIGIL_LOG_LEVEL_ERROR 3
#define VIGIL_LOG_LEVEL_OFF 4

/// Calls below this level are compiled out. Default: every level is compiled in (Debug); the
/// run-time level (Info by default) then decides per component.
#ifndef VIGIL_LOG_LEVEL
#define VIGIL_LOG_LEVEL VIGIL_LOG_LEVEL_DEBUG
#endif

namespace vigil::log {

/// Severity of a log line. `Off` is only a threshold (nothing is logged at Off).
enum class Level : std::uint8_t {
  Debug = VIGIL_LOG_LEVEL_DEBUG,
  Info = VIGIL_LOG_LEVEL_INFO,
  Warn = VIGIL_LOG_LEVEL_WARN,
  Error = VIGIL_LOG_LEVEL_ERROR,
  Off = VIGIL_LOG_LEVEL_OFF,
};

/// "DEBUG", "INFO", "WARN", "ERROR", "OFF". RT-safe.
[[nodiscard]] constexpr const char* to_string(Level l) noexcept {
  switch (l) {
    case Level::Debug:
      return "DEBUG";
    case Level::Info:
      return "INFO";
    case Level::Warn:
      return "WARN";
    case Level::Error:
      return "ERROR";
    case Level::Off:
      return "OFF";
  }
  return "?";
}

/// Parses "debug", "info", "warn" (or "warning"), "error", "off", in any case; nullopt for
/// anything else (the caller names the bad value). RT-safe.
[[nodiscard]] constexpr std::optional<Level> parse_level(std::string_view s) noexcept {
  const auto eq = [](std::string_view a, std::string_view b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
      char c = a[i];
      if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
      if (c != b[i]) return false;
    }
    return true;
  };
  if (eq(s, "debug")) return Level::Debug;
  if (eq(s, "info")) return Level::Info;
  if (eq(s, "warn") || eq(s, "warning")) return Level::Warn;
  if (eq(s, "error")) return Level::Error;
  if (eq(s, "off")) return Level::Off;
  return std::nullopt;
}

}  // namespace vigil::log
