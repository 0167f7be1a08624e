#pragma once
/// @file
/// Reading PEAK-System trace files (`.trc`, written by PCAN-View, PCAN-Explorer and
/// PCAN-Basic's tracer), file versions 1.0 to 1.3, 2.0 and 2.1:
///
///     ;$FILEVERSION=2.1
///     ;$STARTTIME=44548.6028595139
///     ;$COLUMNS=N,O,T,B,I,d,R,L,D
///           1     17535.400 DT 1  00000100 Tx -  8    00 00 00 00 00 00 00 00
///
/// Supported records, the column layouts and how they map to `Frame` are in
/// docs/guide/can-logs.md. Reading streams a line at a time through a fixed buffer.
/// Nothing here is RT-safe.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/can/log/reader.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::can {

/// The `$FILEVERSION` of a trace file (1.0 when the file has none).
enum class TrcVersion : std::uint8_t { V1_0, V1_1, V1_2, V1_3, V2_0, V2_1 };

/// "1.0", "1.1", ..., "2.1". RT-safe: yes.
[[nodiscard]] const char* to_string(TrcVersion v) noexcept;

/**
 * Streaming reader of PEAK trace files.
 *
 * Header lines (`;$FILEVERSION`, `;$STARTTIME`, `;$COLUMNS`) are honoured until the first
 * record; every other line starting with `;` is a comment. Records become frames as follows:
 * data frames (v1 Rx/Tx, v2 DT), remote frames (v1 `RTR` data, v2 RR), CAN FD frames (v2 FD,
 * FB = BRS, FE = ESI, BI = BRS+ESI) and error frames (v1 Error / ERROR, v2 ER; see the guide
 * for the data layout). Status records (v1 Warng and FFFFFFFF lines, v2 ST, EC, EV) are
 * skipped and counted by `skipped_count()`.
 *
 * Timestamps are `$STARTTIME` (days since 1899-12-30, taken as UTC, rounded to the nearest
 * nanosecond) plus the record's offset in milliseconds (exact, up to 6 fraction digits); with
 * no `$STARTTIME` they are the offset alone. The bus column (1-based) gives `frame.bus` =
 * bus - 1; without one every frame is on bus 0.
 *
 * Malformed lines are handled as `ReaderOptions` says. A header that makes the rest unreadable
 * (unknown `$FILEVERSION`, `$COLUMNS` without the needed columns) always fails `next()`.
 * Not thread-safe. Move-only.
 */
class TrcReader {
 public:
  /// Reads from `in`, which must outlive the reader (see CandumpReader for how the stream is
  /// consumed). `source_name` names the stream in error messages. Allocates the 64 KiB buffer.
  /// Not RT-safe.
  explicit TrcReader(std::istream& in, std::string source_name = "<stream>",
                     ReaderOptions options = {});

  /// Opens `path` for reading. Fails with the errno of the open and a message naming the file.
  /// Not RT-safe.
  [[nodiscard]] static expected<TrcReader, Error> open(const std::filesystem::path& path,
                                                       ReaderOptions options = {});

  /// Move-only: the moved-from reader may only be destroyed or assigned to.
  TrcReader(TrcReader&&) noexcept;
  /// Move assignment; see the move constructor.
  TrcReader& operator=(TrcReader&&) noexcept;
  /// Closes the file opened by `open` (a stream passed in is left alone).
  ~TrcReader();

  /// The next frame, or an empty optional at the end of the file. Fails (EINVAL) on a malformed
  /// line when the options say Stop, and on an unusable header; after a failure every call
  /// returns the same error. Does not allocate except to report an error. Exceptions thrown by
  /// `ReaderOptions::on_error` propagate. Not RT-safe (it reads the stream).
  [[nodiscard]] expected<std::optional<LogEntry>, Error> next();
  /// Same as `next()` without copying the entry: a pointer to the reader's own entry (which the
  /// caller may modify), valid until the next call; null at the end of the log.
  [[nodiscard]] expected<LogEntry*, Error> next_entry();

  /// The file version, known once the header has been read (1.0 before and without one).
  /// O(1), noexcept.
  [[nodiscard]] TrcVersion version() const noexcept;
  /// `$STARTTIME` in ns since the Unix epoch, when the header has one. O(1), noexcept.
  [[nodiscard]] std::optional<Nanos> start_time() const noexcept;
  /// Number of malformed lines met so far. O(1), noexcept.
  [[nodiscard]] std::uint64_t malformed_count() const noexcept;
  /// Number of well-formed records that are not frames (status, error counters, events).
  /// O(1), noexcept.
  [[nodiscard]] std::uint64_t skipped_count() const noexcept;
  /// The first `ReaderOptions::max_kept_errors` malformed lines. O(1), noexcept.
  [[nodiscard]] const std::vector<ParseError>& errors() const noexcept;
  /// 1-based number of the last line read (0 before the first `next()`). O(1), noexcept.
  [[nodiscard]] std::uint64_t line_number() const noexcept;
  /// The name used in error messages (the path for `open`). O(1), noexcept.
  [[nodiscard]] const std::string& source_name() const noexcept;

 private:
  struct Impl;
  explicit TrcReader(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

/// Reads a whole trace file into memory. Fails when the file cannot be opened, when its header
/// is unusable or, with `OnMalformed::Stop`, at the first malformed line. Not RT-safe.
[[nodiscard]] expected<CanLog, Error> read_trc_file(const std::filesystem::path& path,
                                                    ReaderOptions options = {});

}  // namespace vigil::can
