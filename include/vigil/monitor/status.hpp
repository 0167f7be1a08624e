#pragma once
/// @file
/// `Status`: what the monitor says about a component, a level and the messages that explain it.
///
/// Levels, from best to worst: Ok < Warn < Error < Stale. Stale ("no data for too long") ranks
/// worst because the other checks ran on old data: a component that stopped reporting may be in
/// any state, including a worse one than the last Error seen. This is ROS diagnostics' order
/// (OK=0, WARN=1, ERROR=2, STALE=3).
///
/// The merge rule (every check merges into one Status per component):
///  1. the worst level wins: merging never makes a status better;
///  2. every non-empty message of every merge is kept, in merge order, with the level it was
///     merged with; nothing is replaced or deduplicated;
///  3. an empty message adds no message and never removes or replaces one (ROS 2's
///     DiagnosticStatusWrapper::mergeSummary replaces the summary with the worse status's
///     message, so a worse status with an empty message erases the explanation).
///
/// Not RT-safe: merging allocates. Monitor-side only.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vigil::monitor {

/// Severity of a status. The numeric values are ROS diagnostics' levels.
enum class StatusLevel : std::uint8_t {
  Ok = 0,     ///< nothing to report
  Warn = 1,   ///< works, but needs attention (near overrun, real-time losses, drops...)
  Error = 2,  ///< misbehaves (exception, overruns above the error rate)
  Stale = 3,  ///< no data for too long (starved, blocked, or its supervisor stopped)
};

/// "OK", "WARN", "ERROR", "STALE" (the JSON and text spelling).
[[nodiscard]] constexpr const char* to_string(StatusLevel level) noexcept {
  switch (level) {
    case StatusLevel::Ok:
      return "OK";
    case StatusLevel::Warn:
      return "WARN";
    case StatusLevel::Error:
      return "ERROR";
    case StatusLevel::Stale:
      return "STALE";
  }
  return "?";
}

/// Parses "OK", "WARN", "ERROR", "STALE" (exact spelling); nullopt otherwise.
[[nodiscard]] std::optional<StatusLevel> parse_status_level(std::string_view text) noexcept;

/// The worse of two levels.
[[nodiscard]] constexpr StatusLevel worst(StatusLevel a, StatusLevel b) noexcept {
  return static_cast<std::uint8_t>(a) >= static_cast<std::uint8_t>(b) ? a : b;
}

/// One explanation in a status, with the level it was merged with.
struct StatusMessage {
  StatusLevel level = StatusLevel::Ok;
  std::string text;

  friend bool operator==(const StatusMessage&, const StatusMessage&) = default;
};

/**
 * A level and its explanations, built by merging (see the file comment for the rule).
 *
 * **Example**:
 * ```
 * vigil::Status s;                                  // OK, no message
 * s.merge(vigil::StatusLevel::Warn, "near overrun");
 * s.merge(vigil::StatusLevel::Error, "");          // ERROR; "near overrun" is kept
 * s.merge(vigil::StatusLevel::Ok, "on cpu 2");     // still ERROR; the message is appended
 * // s.level() == Error
 * // s.messages() == {{Warn, "near overrun"}, {Ok, "on cpu 2"}}
 * ```
 * Not thread-safe (a plain value); not RT-safe (allocates).
 */
class Status {
 public:
  /// OK, no message.
  Status() = default;
  /// `level` with `message` (no message when empty).
  explicit Status(StatusLevel level, std::string message = {});

  /// Merges one finding: the level becomes the worse of both; a non-empty message is appended.
  void merge(StatusLevel level, std::string message = {});
  /// Merges another status: its level, then each of its messages in order.
  void merge(const Status& other);

  [[nodiscard]] StatusLevel level() const noexcept { return level_; }
  [[nodiscard]] const std::vector<StatusMessage>& messages() const noexcept { return messages_; }
  /// True when the level is Ok (there may still be informative messages).
  [[nodiscard]] bool ok() const noexcept { return level_ == StatusLevel::Ok; }
  /// The messages' texts joined by `separator` ("" when there is none).
  [[nodiscard]] std::string summary(std::string_view separator = "; ") const;
  /// Back to OK without messages.
  void clear() noexcept;

  friend bool operator==(const Status&, const Status&) = default;

 private:
  StatusLevel level_ = StatusLevel::Ok;
  std::vector<StatusMessage> messages_;
};

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::parse_status_level;
using monitor::Status;
using monitor::StatusLevel;
using monitor::StatusMessage;
using monitor::to_string;
using monitor::worst;
}  // namespace vigil
