#pragma once
/// @file
/// `ConfigError`: one problem in a configuration file, located by file, line, column and field.
///
/// Every loader in vigil reports bad input as `FILE:LINE:COL: FIELD: MESSAGE`, collects every
/// error of a document instead of stopping at the first, and never falls back to a default
/// silently. Nothing in the config module is RT-safe: it allocates, locks and does file I/O, and
/// the real-time side never reads configuration.

#include <initializer_list>
#include <iosfwd>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace vigil::config {

/// One problem found while loading or validating configuration.
///
/// `line` and `column` are 1-based (column counts characters, not bytes); 0 means unknown (a
/// missing file, an empty document). `field` is the dotted path of the value at fault
/// (`monitor.components.motor.overrun.warn_fraction`, `filters[2].id`), empty for file-level
/// problems such as a syntax error.
struct ConfigError {
  std::string file;     ///< The file name as given to the loader (or a string's name).
  int line = 0;         ///< 1-based line; 0 when unknown.
  int column = 0;       ///< 1-based column in characters; 0 when unknown.
  std::string field;    ///< Dotted path of the value at fault; empty for file-level problems.
  std::string message;  ///< What is wrong, quoting the value as written where there is one.

  /// `file:line:col: field: message`; the line and column are left out when 0, the field when
  /// empty (`cfg.yaml: cannot read file: No such file or directory`). Not RT-safe (allocates).
  [[nodiscard]] std::string to_string() const;

  /// Field-by-field equality (tests compare whole errors).
  friend bool operator==(const ConfigError&, const ConfigError&) = default;
};

/// Every error of a document, in file order (line, then column).
using ConfigErrors = std::vector<ConfigError>;

/// One `ConfigError::to_string()` per line, separated by '\n' (no trailing newline).
/// Not RT-safe (allocates).
[[nodiscard]] std::string to_string(const ConfigErrors& errors);

/// Writes `error.to_string()` (lets test frameworks print errors). Not RT-safe.
std::ostream& operator<<(std::ostream& out, const ConfigError& error);

/// The candidate closest to `word`, for "did you mean 'x'?" hints, or nullopt when none is close.
///
/// Closeness is the optimal-string-alignment edit distance (a swap of two neighbours counts as
/// one edit); a candidate is close when it differs only in letter case or when the distance is at
/// most a third of the longer word (at least 1) and smaller than its length. Ties go to the first
/// candidate. The result
/// points into `candidates`. Not RT-safe (allocates); O(total length²).
[[nodiscard]] std::optional<std::string_view> closest_match(
    std::string_view word, std::span<const std::string_view> candidates);

/// `closest_match` over a braced list: `closest_match(unit, {"ns", "us", "ms", "s"})`.
[[nodiscard]] std::optional<std::string_view> closest_match(
    std::string_view word, std::initializer_list<std::string_view> candidates);

}  // namespace vigil::config
