#pragma once
/// @file
/// `LogRecord`: what one log call sends through its component's port, and `CallSite`, what the
/// record points to: the call site's static description (format string, level, file, line, and
/// the function that decodes the arguments), stored once per call site, never copied.
///
/// Design: a record is fixed-size and trivially copyable (an alternative of the `Message`
/// variant, so it travels through the component's existing port in order with its samples).
/// It holds a pointer to the call site, the component's cycle number and the timestamp of that
/// cycle, the component's cumulative count of dropped log records, and the arguments, packed
/// byte by byte in `payload` (numbers at their natural size; a string as one length byte, whose
/// high bit marks truncation, then at most kMaxStringBytes bytes). The types of the arguments
/// are not in the record: the call site's `decode` knows them. The pointer makes a record
/// meaningful only in the process that logged it.
///
/// This header is a leaf (no fmt, no port): the task module includes it for `Message`.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "vigil/log/level.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::log {

/// Bytes of a string argument copied into a record at most; longer strings are cut (at a UTF-8
/// character boundary) and shown with "..." appended.
inline constexpr std::size_t kMaxStringBytes = 32;
/// Bytes available for the arguments of one record. Numbers take their size (bool and char 1,
/// int 4, double 8, ...), strings one byte plus their (truncated) length.
inline constexpr std::size_t kPayloadBytes = 88;
/// The length byte of a string argument: its low 7 bits are the bytes copied, this bit says
/// the string was longer.
inline constexpr std::uint8_t kTruncatedBit = 0x80;

struct LogRecord;
struct CallSite;

/// Formats `record`'s arguments with `site.format`, appending to `out`. Generated per list of
/// argument types by the logging macros. Supervisor side (allocates, may throw fmt::format_error
/// or std::bad_alloc).
using DecodeFn = void (*)(std::string& out, const CallSite& site, const LogRecord& record);

/// One call site of VIGIL_LOG_*: a `static constexpr` object, one per call site.
struct CallSite {
  Level level = Level::Info;
  std::string_view format;  ///< the fmt format string, checked at compile time
  std::string_view file;    ///< __FILE__
  std::uint32_t line = 0;   ///< __LINE__
  DecodeFn decode = nullptr;
};

/// One log call. Trivially copyable, 120 bytes (so that `Message` stays within 128).
struct LogRecord {
  const CallSite* site = nullptr;
  std::uint64_t cycle = 0;  ///< the component's cycle that logged (1-based)
  Nanos time_ns = 0;        ///< when that cycle's on_update() began (the component's clock)
  /// Records of this component dropped before this one (port full), cumulative; wraps at 2^32.
  std::uint32_t dropped = 0;
  std::uint8_t size = 0;  ///< bytes of `payload` used
  std::uint8_t reserved[3] = {};
  /// The arguments. Deliberately not initialised: a log call writes only what it uses.
  std::array<std::byte, kPayloadBytes> payload;
};

static_assert(sizeof(LogRecord) == 120, "LogRecord must stay 120 bytes (Message <= 128)");
static_assert(alignof(LogRecord) <= 8);
static_assert(kMaxStringBytes < kTruncatedBit && kPayloadBytes < 256);

}  // namespace vigil::log
