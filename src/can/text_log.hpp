#pragma once
// Private to the can module: the machinery the text log readers (candump, TRC) share.
//
// Design: a reader owns one LineReader (a fixed block buffer over a std::streambuf, handing
// out string_views into it) and one ReaderCore (error policy, counters, sticky failure).
// Parsers work on the string_view of one line with hand-written scanning and never allocate
// unless they report a problem, so steady-state reading allocates nothing.

#include <array>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <memory>
#include <optional>
#include <streambuf>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/can/log_reader.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::can::detail {

/// Value of a hex digit, or 0xFF for any other byte.
inline constexpr std::array<std::uint8_t, 256> kHexValue = [] {
  std::array<std::uint8_t, 256> t{};
  for (auto& v : t) v = 0xFF;
  for (int c = '0'; c <= '9'; ++c)
    t[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(c - '0');
  for (int c = 'A'; c <= 'F'; ++c)
    t[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(c - 'A' + 10);
  for (int c = 'a'; c <= 'f'; ++c)
    t[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(c - 'a' + 10);
  return t;
}();

inline std::uint8_t hex_value(char c) noexcept { return kHexValue[static_cast<unsigned char>(c)]; }
inline bool is_digit(char c) noexcept { return c >= '0' && c <= '9'; }
inline bool is_blank(char c) noexcept { return c == ' ' || c == '\t'; }

/// A problem found in a line: where (0-based offset in the line) and what.
struct Problem {
  std::size_t offset = 0;
  std::string message;
};

/// Hands out the lines of a stream as string_views into a fixed buffer (valid until the next
/// call). Memory is one block allocated at construction, whatever the input.
class LineReader {
 public:
  enum class Status : std::uint8_t { Line, TooLong, End };

  LineReader(std::streambuf* source, std::size_t max_line_bytes);

  /// Next line without its '\n' and one trailing '\r' (and, on line 1, without a UTF-8 byte
  /// order mark). A line longer than the maximum is skipped up to its end and reported as
  /// TooLong (it still counts as a line).
  Status next(std::string_view& line);

  [[nodiscard]] std::uint64_t line_number() const noexcept { return line_number_; }
  [[nodiscard]] std::size_t max_line_bytes() const noexcept { return max_line_; }

 private:
  bool fill();  // reads more input after end_; false at end of input
  Status skip_long_line();
  void strip_bom(std::string_view& line) const noexcept;

  std::streambuf* source_;
  std::size_t max_line_;
  std::size_t capacity_;
  std::unique_ptr<char[]> buffer_;
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  bool eof_ = false;
  std::uint64_t line_number_ = 0;
};

/// Error policy, counters and the sticky failure of a reader.
class ReaderCore {
 public:
  ReaderCore(std::string source, ReaderOptions options);

  /// Records a malformed line. Returns true when reading goes on (Skip), false when the reader
  /// has now failed (Stop); `failure()` then holds the error.
  bool report(std::uint64_t line, std::size_t offset, std::string message);
  /// Records a problem after which nothing can be read, whatever the policy.
  void fail(std::uint64_t line, std::size_t offset, std::string message);

  [[nodiscard]] const std::optional<Error>& failure() const noexcept { return failure_; }
  [[nodiscard]] std::uint64_t malformed_count() const noexcept { return malformed_; }
  [[nodiscard]] const std::vector<ParseError>& errors() const noexcept { return kept_; }
  [[nodiscard]] const std::string& source() const noexcept { return source_; }
  [[nodiscard]] const ReaderOptions& options() const noexcept { return options_; }

 private:
  ParseError record(std::uint64_t line, std::size_t offset, std::string message);

  std::string source_;
  ReaderOptions options_;
  std::uint64_t malformed_ = 0;
  std::vector<ParseError> kept_;
  std::optional<Error> failure_;
};

/// Opens `path` as a binary input stream; the error names the file and carries errno.
expected<std::unique_ptr<std::istream>, Error> open_input(const std::string& path);

/// Adds `a * b + c` into `out`; false on overflow of int64.
inline bool mul_add(std::int64_t a, std::int64_t b, std::int64_t c, std::int64_t& out) noexcept {
  std::int64_t product = 0;
  return !__builtin_mul_overflow(a, b, &product) && !__builtin_add_overflow(product, c, &out);
}

/// Powers of ten 10^0 .. 10^18.
inline constexpr std::array<std::int64_t, 19> kPow10 = [] {
  std::array<std::int64_t, 19> p{};
  p[0] = 1;
  for (std::size_t i = 1; i < p.size(); ++i) p[i] = p[i - 1] * 10;
  return p;
}();

}  // namespace vigil::can::detail
