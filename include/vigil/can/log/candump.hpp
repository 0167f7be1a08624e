#pragma once
/// @file
/// Reading and writing the log format of can-utils (`candump -l`, read by `canplayer` and
/// `log2asc`): one frame per line,
///
///     (1648583717.428998) can1 0CF00400#707D83C312000F84
///     (1648583717.430971) vcan0 123##1112233 T
///
/// The full grammar, and what is accepted beyond what candump writes, is in
/// docs/guide/can-logs.md. Reading streams a line at a time through a fixed buffer, so memory
/// does not depend on the file's size. Nothing here is RT-safe.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/can/log/reader.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::can {

/**
 * Streaming reader of candump log files.
 *
 * Each `next()` returns the next frame of the log, with its direction when the line ends in
 * ` R` or ` T` (`candump -x`). Interface names are given bus indices 0, 1, ... in order of first
 * appearance; `interfaces()[frame.bus]` is the name. Lines that do not start with `(` are
 * comments (candump's own rule, which also skips DROPCOUNT lines and empty lines).
 * Timestamps are exact: `(sec.frac)` with 1 to 9 fraction digits is sec * 10^9 + frac scaled
 * to nanoseconds, with no floating point.
 *
 * Malformed lines are counted and reported as `source:line:column: message`; `ReaderOptions`
 * says whether the reader skips them or stops. Memory is a 64 KiB line buffer plus the
 * interface table: after the first lines, reading does not allocate.
 *
 * @code
 * auto reader = vigil::can::CandumpReader::open("drive.log");
 * if (!reader) return fail(reader.error().message);
 * for (;;) {
 *   auto entry = reader->next();
 *   if (!entry) return fail(entry.error().message);  // only with OnMalformed::Stop
 *   if (!*entry) break;                               // end of the log
 *   use((*entry)->frame, reader->interfaces()[(*entry)->frame.bus]);
 * }
 * @endcode
 *
 * Not thread-safe; one thread uses a reader at a time. Move-only.
 */
class CandumpReader {
 public:
  /// Reads from `in`, which must outlive the reader. The reader pulls bytes straight from
  /// `in.rdbuf()` in blocks (it does not update `in`'s state flags, and consumes the stream
  /// beyond the line it returned). `source_name` names the stream in error messages.
  /// Allocates the 64 KiB buffer; throws std::bad_alloc only if that fails. Not RT-safe.
  explicit CandumpReader(std::istream& in, std::string source_name = "<stream>",
                         ReaderOptions options = {});

  /// Opens `path` for reading. Fails with the errno of the open (ENOENT, EACCES, EISDIR ...)
  /// and a message naming the file. Not RT-safe.
  [[nodiscard]] static expected<CandumpReader, Error> open(const std::filesystem::path& path,
                                                           ReaderOptions options = {});

  /// Move-only: the moved-from reader may only be destroyed or assigned to.
  CandumpReader(CandumpReader&&) noexcept;
  /// Move assignment; see the move constructor.
  CandumpReader& operator=(CandumpReader&&) noexcept;
  /// Closes the file opened by `open` (a stream passed in is left alone).
  ~CandumpReader();

  /// The next frame, or an empty optional at the end of the log. Fails (EINVAL) on a malformed
  /// line when the options say Stop; after a failure every call returns the same error.
  /// Amortised O(line length); does not allocate once the interface table is filled, except
  /// to report an error. Exceptions thrown by `ReaderOptions::on_error` propagate. Not RT-safe
  /// (it reads the stream).
  [[nodiscard]] expected<std::optional<LogEntry>, Error> next();
  /// Same as `next()` without copying the entry: a pointer to the reader's own entry (which the
  /// caller may modify), valid until the next call; null at the end of the log.
  [[nodiscard]] expected<LogEntry*, Error> next_entry();

  /// Interface names by bus index, in order of first appearance so far. O(1), noexcept.
  [[nodiscard]] const std::vector<std::string>& interfaces() const noexcept;
  /// Number of malformed lines met so far. O(1), noexcept.
  [[nodiscard]] std::uint64_t malformed_count() const noexcept;
  /// The first `ReaderOptions::max_kept_errors` malformed lines. O(1), noexcept.
  [[nodiscard]] const std::vector<ParseError>& errors() const noexcept;
  /// 1-based number of the last line read (0 before the first `next()`). O(1), noexcept.
  [[nodiscard]] std::uint64_t line_number() const noexcept;
  /// The name used in error messages (the path for `open`). O(1), noexcept.
  [[nodiscard]] const std::string& source_name() const noexcept;

 private:
  struct Impl;
  explicit CandumpReader(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

/// Reads a whole candump log into memory. Fails when the file cannot be opened or, with
/// `OnMalformed::Stop`, at the first malformed line; otherwise malformed lines are counted in
/// the result. Memory: the frames (88 bytes each) plus the reader's fixed buffer.
/// Not RT-safe.
[[nodiscard]] expected<CanLog, Error> read_candump_file(const std::filesystem::path& path,
                                                        ReaderOptions options = {});

/**
 * Parses the frame field of a candump line (also the syntax of `cansend`):
 * `123#1122`, `12345678#R`, `123##1AABB`, `20000004#0004000000000000`, ...
 * Fails (EINVAL) with a message giving the 1-based column of the problem, e.g.
 * "column 5: odd number of hex digits in data". Not RT-safe (allocates on failure only).
 */
[[nodiscard]] expected<Frame, Error> parse_candump_frame(std::string_view text);

/// Number of fraction digits `write_candump_line` gives timestamps.
enum class TimestampDigits : std::uint8_t {
  Micro = 6,  ///< `candump -l` (default): microseconds, truncated as candump truncates
  Nano = 9,   ///< `candump -l -N`: nanoseconds
};

/// How `write_candump_line` writes.
struct CandumpWriteOptions {
  TimestampDigits digits = TimestampDigits::Micro;  ///< fraction digits of the timestamp
};

/**
 * Appends one line in exactly the form `candump -l` writes, newline included:
 * `(%010llu.%06llu) iface frame[ R| T]\n`. Ids are 3 (standard) or 8 (extended, error) upper
 * case hex digits; CAN FD frames are written `##` with the flags nibble CANFD_FDF|BRS|ESI
 * (4..7), as can-utils does since release 2025.01; remote frames `R` plus the DLC when it is not 0;
 * Classical CAN DLCs 9..15 with the `_` suffix. A negative timestamp is written as 0, since
 * candump has no way to write one. Frames that are not `valid()` are written the way candump
 * writes the equivalent struct canfd_frame (id masked to its format, data cut to 8 or 64).
 * `iface` is written as given: it must be non-empty and free of blanks for the line to be
 * readable. Cannot fail; allocates only when `out` grows. Not RT-safe.
 */
void write_candump_line(std::string& out, const Frame& frame, std::string_view iface,
                        std::optional<Direction> direction = std::nullopt,
                        CandumpWriteOptions options = {});

/// Same as above, to a stream (one `write` call per line). Stream errors are left in `out`'s
/// state for the caller to check. Not RT-safe.
void write_candump_line(std::ostream& out, const Frame& frame, std::string_view iface,
                        std::optional<Direction> direction = std::nullopt,
                        CandumpWriteOptions options = {});

/// Writes `entries` to `path` (created or truncated), naming bus i `interfaces[i]`, or `can<i>`
/// when `interfaces` has no such entry. Fails with errno and a message naming the file when
/// it cannot be opened or written. Not RT-safe.
[[nodiscard]] expected<void, Error> write_candump_file(const std::filesystem::path& path,
                                                       std::span<const LogEntry> entries,
                                                       std::span<const std::string> interfaces,
                                                       CandumpWriteOptions options = {});

}  // namespace vigil::can
