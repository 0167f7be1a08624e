#pragma once
// Private to the can module: the machinery every text log reader (candump, TRC) shares.
//
// Design: a reader's Impl owns one TextLog: the input stream (when the reader opened it), a
// LineReader (a fixed block buffer over a std::streambuf, handing out string_views into it),
// the error policy, the counters and the sticky failure. A format only writes its line parser,
// `LineOutcome parse(std::string_view line)`, and calls `TextLog::next(problem, parse)`.
// Parsers work on the string_view of one line with hand-written scanning and never allocate
// unless they report a problem, so steady-state reading allocates nothing.

#include <array>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <memory>
#include <optional>
#include <streambuf>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "vigil/can/log/reader.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

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

/// What a format's parser made of one line.
enum class LineOutcome : std::uint8_t {
  Frame,      ///< the parser stored a frame: `TextLog::next` returns it
  Comment,    ///< nothing to return (comment, header line, blank line)
  Skipped,    ///< a well-formed record that is not a frame (counted in `skipped_count()`)
  Malformed,  ///< the problem is reported; the policy says whether reading goes on
  Fatal,      ///< the problem is reported and reading stops, whatever the policy
};

/// The line loop of a text log reader: input, lines, error policy, counters, sticky failure.
class TextLog {
 public:
  /// Reads `in` (owned when `owned` is set, e.g. by `open_text_log`). Allocates the buffer.
  TextLog(std::unique_ptr<std::istream> owned, std::istream& in, std::string source,
          ReaderOptions options);

  /// Hands each line to `parse(line)` (which describes a bad line in `problem`) until one
  /// gives a frame (true) or the input ends (false). Malformed lines are reported and skipped
  /// or stop the reader as the options say; a Fatal one always stops it. Once failed, every
  /// call returns the same error.
  template <class Parse>
  expected<bool, Error> next(Problem& problem, Parse&& parse) {
    if (failure_) return unexpected(*failure_);
    for (;;) {
      std::string_view line;
      const LineReader::Status status = lines_.next(line);
      if (status == LineReader::Status::End) return false;
      LineOutcome outcome = LineOutcome::Malformed;
      if (status == LineReader::Status::TooLong) {
        problem = too_long();
      } else {
        outcome = parse(line);
      }
      switch (outcome) {
        case LineOutcome::Frame:
          return true;
        case LineOutcome::Comment:
          continue;
        case LineOutcome::Skipped:
          ++skipped_;
          continue;
        case LineOutcome::Malformed:
          if (report(problem)) continue;
          return unexpected(*failure_);
        case LineOutcome::Fatal:
          fail(problem);
          return unexpected(*failure_);
      }
    }
  }

  [[nodiscard]] std::uint64_t malformed_count() const noexcept { return malformed_; }
  [[nodiscard]] std::uint64_t skipped_count() const noexcept { return skipped_; }
  [[nodiscard]] const std::vector<ParseError>& errors() const noexcept { return kept_; }
  [[nodiscard]] std::uint64_t line_number() const noexcept { return lines_.line_number(); }
  [[nodiscard]] const std::string& source() const noexcept { return source_; }

 private:
  [[nodiscard]] Problem too_long() const;
  ParseError record(Problem& problem);
  // Records a malformed line; true when reading goes on (Skip), false when the reader failed.
  bool report(Problem& problem);
  // Records a problem after which nothing can be read, whatever the policy.
  void fail(Problem& problem);

  std::unique_ptr<std::istream> owned_;  // set by open_text_log; lines_ reads its buffer
  LineReader lines_;
  std::string source_;
  ReaderOptions options_;
  std::uint64_t malformed_ = 0;
  std::uint64_t skipped_ = 0;
  std::vector<ParseError> kept_;
  std::optional<Error> failure_;
};

/// Opens `path` as a binary input stream; the error names the file and carries errno.
expected<std::unique_ptr<std::istream>, Error> open_input(const std::string& path);

/// Makes a reader's Impl (constructible from `(unique_ptr<istream>, istream&, string source,
/// ReaderOptions)`) over the file at `path`; fails as `open_input`.
template <class Impl>
expected<std::unique_ptr<Impl>, Error> open_text_log(const std::string& path,
                                                     ReaderOptions options) {
  auto in = open_input(path);
  if (!in) return unexpected(in.error());
  std::istream& stream = **in;
  return std::make_unique<Impl>(std::move(*in), stream, path, std::move(options));
}

/// Reads every remaining frame of `reader` (CandumpReader, TrcReader) into a CanLog with the
/// reader's malformed count and kept errors. Fails as the reader's `next`.
template <class Reader>
expected<CanLog, Error> read_entries(Reader& reader) {
  CanLog log;
  for (;;) {
    auto entry = reader.next();
    if (!entry) return unexpected(entry.error());
    if (!*entry) break;
    log.entries.push_back(**entry);
  }
  log.malformed = reader.malformed_count();
  log.errors = reader.errors();
  return log;
}

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
