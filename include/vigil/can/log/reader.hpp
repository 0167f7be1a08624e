#pragma once
/// @file
/// What the CAN log readers share: the record they return (`LogEntry`), how they describe a
/// malformed line (`ParseError`), what they do about it (`ReaderOptions`) and the result of
/// reading a whole file (`CanLog`). The readers themselves are in candump.hpp and trc.hpp.
///
/// None of this is RT-safe: log reading is an offline or supervisor-side activity.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "vigil/can/frame.hpp"

namespace vigil::can {

/// One frame read from a log, with the direction when the log records it.
struct LogEntry {
  Frame frame;                         ///< the frame; `frame.bus` indexes the log's interfaces
  std::optional<Direction> direction;  ///< Rx/Tx when the line says so, else empty

  /// Equal frames (see Frame's operator==) and equal directions. RT-safe: yes.
  friend bool operator==(const LogEntry&, const LogEntry&) = default;
};

/// A line of a log that could not be read, located to the byte.
struct ParseError {
  std::string source;        ///< file name, or the name given for a stream
  std::uint64_t line = 0;    ///< 1-based line number
  std::uint32_t column = 0;  ///< 1-based byte column where the problem starts; 0 when unknown
  std::string message;       ///< what is wrong, e.g. "odd number of hex digits in data"

  /// "source:line:column: message" (without ":column" when it is 0), the form compilers use
  /// so that editors can jump to it. Allocates; not RT-safe.
  [[nodiscard]] std::string to_string() const;
};

/// What a reader does when a line is malformed.
enum class OnMalformed : std::uint8_t {
  Skip,  ///< count it, report it (callback, first `max_kept_errors`), go on with the next line
  Stop,  ///< `next()` returns an error naming source:line:column; the reader stays failed
};

/// Options shared by every CAN log reader.
struct ReaderOptions {
  /// Skip malformed lines (default) or stop at the first one.
  OnMalformed on_malformed = OnMalformed::Skip;
  /// How many `ParseError`s the reader keeps for `errors()`; later ones are only counted.
  std::size_t max_kept_errors = 100;
  /// Called for every malformed line, in order, before `next()` returns (optional).
  std::function<void(const ParseError&)> on_error;
  /// Longest line accepted, in bytes without the line end. A longer line is malformed and is
  /// skipped without being stored, so that memory stays bounded whatever the input.
  std::size_t max_line_bytes = 4096;
};

/// A whole log read into memory (by `read_candump_file`, `read_trc_file`).
struct CanLog {
  std::vector<LogEntry> entries;        ///< every frame, in file order
  std::vector<std::string> interfaces;  ///< name of each bus index (candump); empty for TRC
  std::uint64_t malformed = 0;          ///< number of malformed lines (skipped)
  std::uint64_t skipped = 0;            ///< well-formed records that are not frames (TRC status)
  std::vector<ParseError> errors;       ///< the first `max_kept_errors` malformed lines
};

}  // namespace vigil::can
