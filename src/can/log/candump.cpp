// candump log format (can-utils lib.c parse_canframe / snprintf_canframe, candump.c, log2asc.c):
// reader, frame parser and writer.
#include "vigil/can/log/candump.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <istream>
#include <ostream>
#include <utility>

#include "can/log/line_reader.hpp"

namespace vigil::can {

namespace {

using detail::hex_value;
using detail::is_blank;
using detail::is_digit;
using detail::Problem;

constexpr std::uint32_t kErrFlag = 0x20000000U;  // CAN_ERR_FLAG as written in 8-digit ids
constexpr std::uint8_t kFdFlagBrs = 0x1;         // CANFD_BRS
constexpr std::uint8_t kFdFlagEsi = 0x2;         // CANFD_ESI
constexpr std::uint8_t kFdFlagFdf = 0x4;         // CANFD_FDF (marks CAN FD; implied by "##")
constexpr std::size_t kMaxInterfaces = 256;      // bus indices are 8 bits

bool fail(Problem& p, std::size_t offset, std::string message) {
  p.offset = offset;
  p.message = std::move(message);
  return false;
}

std::string quote(char c) {
  const auto u = static_cast<unsigned char>(c);
  if (u >= 0x20 && u < 0x7F) return fmt::format("'{}'", c);
  return fmt::format("byte 0x{:02X}", u);
}

// The identifier of the frame field `s` (which starts at offset `base` of its line), read from
// `pos` = 0 up to the '#' it leaves `pos` on: 3 hex digits (standard), 8 (extended, or an error
// frame's class with CAN_ERR_FLAG).
bool parse_identifier(std::string_view s, std::size_t base, std::size_t& pos, Frame& f,
                      Problem& p) {
  const std::size_t n = s.size();
  std::uint32_t raw = 0;
  while (pos < n && s[pos] != '#') {
    const std::uint8_t v = hex_value(s[pos]);
    if (v > 0xF) {
      return fail(p, base + pos, fmt::format("invalid character {} in identifier", quote(s[pos])));
    }
    if (pos < 8) raw = (raw << 4) | v;
    ++pos;
  }
  if (pos == n) return fail(p, base + n, "missing '#' after the identifier");
  switch (pos) {
    case 3:
      if (raw > kMaxStandardId) {
        return fail(p, base, fmt::format("standard identifier {:03X} exceeds 7FF", raw));
      }
      f.id = raw;
      return true;
    case 8:
      if (raw > (kErrFlag | kMaxExtendedId)) {
        return fail(p, base, fmt::format("identifier {:08X} has bits above the 29-bit id", raw));
      }
      if ((raw & kErrFlag) != 0) {
        f.error = true;
        f.id = raw & kMaxExtendedId;
      } else {
        f.extended = true;
        f.id = raw;
      }
      return true;
    case 5:
      return fail(p, base, "CAN XL frames (5-digit priority field) are not supported");
    default:
      return fail(
          p, base,
          fmt::format("identifier has {} hex digits; expected 3 (standard) or 8 (extended)", pos));
  }
}

// A remote frame, from the 'R' at `pos` to the end: R, optional length digit 0..8, and after 8
// an optional raw DLC "_9".."_F".
bool parse_remote(std::string_view s, std::size_t base, std::size_t pos, Frame& f, Problem& p) {
  const std::size_t n = s.size();
  if (f.error) return fail(p, base + pos, "an error frame cannot be a remote frame");
  f.rtr = true;
  ++pos;
  if (pos < n && s[pos] != '_') {
    if (s[pos] < '0' || s[pos] > '8') {
      return fail(
          p, base + pos,
          fmt::format("remote frame length must be one digit 0-8, found {}", quote(s[pos])));
    }
    f.length = static_cast<std::uint8_t>(s[pos] - '0');
    ++pos;
  }
  if (pos < n && s[pos] == '_') {
    if (f.length != 8) return fail(p, base + pos, "a raw DLC ('_') must follow the length 8");
    ++pos;
    const std::uint8_t dlc = pos < n ? hex_value(s[pos]) : 0xFF;
    if (dlc < 9 || dlc > 15) return fail(p, base + pos, "raw DLC after '_' must be one of 9-F");
    f.length = dlc;
    ++pos;
  }
  if (pos != n) {
    return fail(p, base + pos, fmt::format("unexpected {} after the remote frame", quote(s[pos])));
  }
  return true;
}

// The CAN FD flags digit after the second '#' at `pos`; leaves `pos` after it.
bool parse_fd_flags(std::string_view s, std::size_t base, std::size_t& pos, Frame& f, Problem& p) {
  if (f.error) return fail(p, base + pos, "an error frame cannot be a CAN FD frame");
  ++pos;
  const std::uint8_t flags = pos < s.size() ? hex_value(s[pos]) : 0xFF;
  if (flags > 0xF) return fail(p, base + pos, "CAN FD flags after '##' must be one hex digit");
  if ((flags & ~(kFdFlagBrs | kFdFlagEsi | kFdFlagFdf)) != 0) {
    return fail(p, base + pos, fmt::format("unknown CAN FD flag bits in {:X}", flags));
  }
  f.fd = true;
  f.brs = (flags & kFdFlagBrs) != 0;
  f.esi = (flags & kFdFlagEsi) != 0;
  ++pos;
  return true;
}

// The data bytes from `pos` (hex pairs, optionally separated by single '.'), up to the end or a
// '_' it leaves `pos` on; sets the length.
bool parse_data(std::string_view s, std::size_t base, std::size_t& pos, Frame& f, Problem& p) {
  const std::size_t n = s.size();
  const std::size_t max_bytes = f.fd ? kMaxFdDataLength : kMaxClassicDataLength;
  const std::size_t data_start = pos;
  std::size_t count = 0;
  while (true) {
    if (pos < n && s[pos] == '.') ++pos;  // optional separator, one at a time
    if (pos >= n || s[pos] == '_') break;
    const std::uint8_t hi = hex_value(s[pos]);
    if (hi > 0xF) {
      return fail(p, base + pos, fmt::format("invalid character {} in data", quote(s[pos])));
    }
    if (pos + 1 >= n) return fail(p, base + pos, "odd number of hex digits in data");
    const std::uint8_t lo = hex_value(s[pos + 1]);
    if (lo > 0xF) {
      return fail(p, base + pos + 1,
                  fmt::format("invalid character {} in data", quote(s[pos + 1])));
    }
    if (count == max_bytes) {
      if (f.fd) return fail(p, base + pos, "more than 64 data bytes");
      return fail(p, base + pos,
                  f.error ? "more than 8 data bytes in an error frame"
                          : "more than 8 data bytes in a Classical CAN frame (CAN FD is "
                            "written with '##')");
    }
    f.data[count++] = static_cast<std::uint8_t>((hi << 4) | lo);
    pos += 2;
  }
  f.length = static_cast<std::uint8_t>(count);
  if (f.fd && !is_fd_length(count)) {
    return fail(
        p, base + data_start,
        fmt::format("{} data bytes is not a CAN FD length (0-8, 12, 16, 20, 24, 32, 48, 64)",
                    count));
  }
  return true;
}

// The raw DLC "_9".."_F" of a Classical CAN frame with 8 data bytes, from the '_' at `pos` to
// the end.
bool parse_raw_dlc(std::string_view s, std::size_t base, std::size_t pos, Frame& f, Problem& p) {
  const std::size_t n = s.size();
  if (f.fd) return fail(p, base + pos, "a CAN FD frame has no raw DLC ('_')");
  if (f.error) return fail(p, base + pos, "an error frame has no raw DLC ('_')");
  if (f.length != kMaxClassicDataLength) {
    return fail(p, base + pos, "a raw DLC ('_') needs 8 data bytes before it");
  }
  ++pos;
  const std::uint8_t dlc = pos < n ? hex_value(s[pos]) : 0xFF;
  if (dlc < 9 || dlc > 15) return fail(p, base + pos, "raw DLC after '_' must be one of 9-F");
  f.length = dlc;
  ++pos;
  if (pos != n) {
    return fail(p, base + pos, fmt::format("unexpected {} after the raw DLC", quote(s[pos])));
  }
  return true;
}

// Parses the frame field `s` (which starts at offset `base` of its line) into `f`.
bool parse_frame(std::string_view s, std::size_t base, Frame& f, Problem& p) {
  f = Frame{};
  std::size_t pos = 0;
  if (!parse_identifier(s, base, pos, f, p)) return false;
  ++pos;  // '#'
  if (pos < s.size() && (s[pos] == 'R' || s[pos] == 'r')) return parse_remote(s, base, pos, f, p);
  if (pos < s.size() && s[pos] == '#' && !parse_fd_flags(s, base, pos, f, p)) return false;
  if (!parse_data(s, base, pos, f, p)) return false;
  return pos == s.size() || parse_raw_dlc(s, base, pos, f, p);  // '_': a raw DLC
}

enum class LineKind : std::uint8_t { Frame, Comment, Malformed };

// What `parse_line` fills: the frame and direction in place (the reader's entry), the interface.
struct ParsedLine {
  Frame* frame = nullptr;
  std::optional<Direction>* direction = nullptr;
  std::string_view iface;
  std::size_t iface_offset = 0;
};

std::size_t skip_blanks(std::string_view s, std::size_t pos) {
  while (pos < s.size() && is_blank(s[pos])) ++pos;
  return pos;
}

std::size_t token_end(std::string_view s, std::size_t pos) {
  // memchr is vectorised: a byte loop over the ~30 bytes of a frame field costs more.
  const char* begin = s.data() + pos;
  const char* end = s.data() + s.size();
  if (const void* space = std::memchr(begin, ' ', static_cast<std::size_t>(end - begin))) {
    end = static_cast<const char*>(space);
  }
  if (const void* tab = std::memchr(begin, '\t', static_cast<std::size_t>(end - begin))) {
    end = static_cast<const char*>(tab);
  }
  return static_cast<std::size_t>(end - s.data());
}

LineKind malformed(Problem& p, std::size_t offset, std::string message) {
  fail(p, offset, std::move(message));
  return LineKind::Malformed;
}

// "(sec.frac) iface frame [R|T]"; lines not starting with '(' are comments (candump, log2asc).
LineKind parse_line(std::string_view line, ParsedLine& out, Problem& p) {
  if (line.empty() || line[0] != '(') return LineKind::Comment;
  const std::size_t n = line.size();
  std::size_t pos = 1;

  // Timestamp: exact integer arithmetic, 1..9 fraction digits.
  std::uint64_t sec_digits = 0;
  const std::size_t sec_start = pos;
  while (pos < n && is_digit(line[pos])) {
    sec_digits = sec_digits * 10 + static_cast<std::uint64_t>(line[pos] - '0');
    ++pos;
  }
  if (pos == sec_start) return malformed(p, pos, "timestamp: expected digits after '('");
  // 11 digits already overflow int64 nanoseconds; checking the count first keeps the loop plain.
  if (pos - sec_start > 11) return malformed(p, sec_start, "timestamp out of range");
  const auto sec = static_cast<std::int64_t>(sec_digits);
  if (pos >= n || line[pos] != '.')
    return malformed(p, pos, "timestamp: expected '.' after the seconds");
  ++pos;
  const std::size_t frac_start = pos;
  std::int64_t frac = 0;
  while (pos < n && is_digit(line[pos])) {
    if (pos - frac_start == 9) {
      return malformed(p, pos,
                       "timestamp has more than 9 fraction digits (the resolution is 1 ns)");
    }
    frac = frac * 10 + (line[pos] - '0');
    ++pos;
  }
  if (pos == frac_start) return malformed(p, pos, "timestamp: expected digits after '.'");
  if (pos >= n || line[pos] != ')') return malformed(p, pos, "timestamp: expected ')'");
  ++pos;
  frac *= detail::kPow10[9 - (pos - 1 - frac_start)];
  std::int64_t ts = 0;
  if (!detail::mul_add(sec, kNanosPerSecond, frac, ts)) {
    return malformed(p, sec_start, "timestamp out of range");
  }

  if (pos >= n) return malformed(p, pos, "missing interface name and frame after the timestamp");
  if (!is_blank(line[pos])) return malformed(p, pos, "expected a space after the timestamp");
  pos = skip_blanks(line, pos);
  if (pos >= n) return malformed(p, pos, "missing interface name and frame after the timestamp");
  const std::size_t iface_start = pos;
  pos = token_end(line, pos);
  const std::string_view iface = line.substr(iface_start, pos - iface_start);
  pos = skip_blanks(line, pos);
  if (pos >= n) {
    if (iface.find('#') != std::string_view::npos) {
      return malformed(p, iface_start, "missing interface name before the frame");
    }
    return malformed(p, pos, "missing frame after the interface name");
  }
  const std::size_t frame_start = pos;
  pos = token_end(line, pos);
  if (!parse_frame(line.substr(frame_start, pos - frame_start), frame_start, *out.frame, p)) {
    return LineKind::Malformed;
  }
  out.frame->timestamp = ts;

  // Optional direction (candump -x): " R" or " T", nothing after it but blanks.
  out.direction->reset();
  pos = skip_blanks(line, pos);
  if (pos < n) {
    const std::size_t dir_end = token_end(line, pos);
    if (dir_end - pos != 1 || (line[pos] != 'R' && line[pos] != 'T')) {
      return malformed(p, pos,
                       "unexpected text after the frame (only a direction R or T may follow)");
    }
    *out.direction = line[pos] == 'T' ? Direction::Tx : Direction::Rx;
    if (skip_blanks(line, dir_end) != n) {
      return malformed(p, skip_blanks(line, dir_end), "unexpected text after the direction");
    }
  }
  out.iface = iface;
  out.iface_offset = iface_start;
  return LineKind::Frame;
}

constexpr char kHexUpper[] = "0123456789ABCDEF";

void put_hex(fmt::memory_buffer& b, std::uint32_t v, int digits) {
  for (int i = digits - 1; i >= 0; --i) b.push_back(kHexUpper[(v >> (4 * i)) & 0xF]);
}

// The exact bytes of one `candump -l` line (snprintf_canframe + sprint_timestamp).
void format_line(fmt::memory_buffer& b, const Frame& f, std::string_view iface,
                 std::optional<Direction> direction, CandumpWriteOptions options) {
  const Nanos ts = f.timestamp < 0 ? 0 : f.timestamp;
  const auto sec = static_cast<unsigned long long>(ts / kNanosPerSecond);
  const auto ns = static_cast<unsigned long long>(ts % kNanosPerSecond);
  if (options.digits == TimestampDigits::Nano) {
    fmt::format_to(std::back_inserter(b), "({:010}.{:09}) ", sec, ns);
  } else {
    fmt::format_to(std::back_inserter(b), "({:010}.{:06}) ", sec, ns / 1000);
  }
  b.append(iface.data(), iface.data() + iface.size());
  b.push_back(' ');

  if (f.error) {
    put_hex(b, (f.id & kMaxExtendedId) | kErrFlag, 8);
  } else if (f.extended) {
    put_hex(b, f.id & kMaxExtendedId, 8);
  } else {
    put_hex(b, f.id & kMaxStandardId, 3);
  }
  b.push_back('#');
  const bool fd = f.fd && !f.error;
  if (!fd && f.rtr && !f.error) {
    b.push_back('R');
    const std::uint8_t len = std::min(f.length, kMaxDlc);
    if (len > 0 && len <= 8) {
      b.push_back(kHexUpper[len]);
    } else if (len > 8) {
      b.push_back('8');
      b.push_back('_');
      b.push_back(kHexUpper[len]);
    }
  } else {
    std::size_t len = 0;
    if (fd) {
      b.push_back('#');
      b.push_back(kHexUpper[kFdFlagFdf | (f.brs ? kFdFlagBrs : 0) | (f.esi ? kFdFlagEsi : 0)]);
      len = std::min<std::size_t>(f.length, kMaxFdDataLength);
    } else {
      len = std::min<std::size_t>(f.length, kMaxClassicDataLength);
    }
    for (std::size_t i = 0; i < len; ++i) put_hex(b, f.data[i], 2);
    if (!fd && !f.error && f.length > kMaxClassicDataLength) {
      b.push_back('_');
      b.push_back(kHexUpper[std::min(f.length, kMaxDlc)]);
    }
  }
  if (direction) {
    b.push_back(' ');
    b.push_back(*direction == Direction::Tx ? 'T' : 'R');
  }
  b.push_back('\n');
}

}  // namespace

// --- reader ------------------------------------------------------------------------------------

struct CandumpReader::Impl {
  Impl(std::unique_ptr<std::istream> owned, std::istream& in, std::string source,
       ReaderOptions options)
      : text(std::move(owned), in, std::move(source), std::move(options)) {}

  // Bus index of `name`, adding it on first appearance; false when the table is full.
  bool bus_of(std::string_view name, std::uint8_t& bus) {
    if (last_bus < interfaces.size() && interfaces[last_bus] == name) {
      bus = static_cast<std::uint8_t>(last_bus);
      return true;
    }
    for (std::size_t i = 0; i < interfaces.size(); ++i) {
      if (interfaces[i] == name) {
        last_bus = i;
        bus = static_cast<std::uint8_t>(i);
        return true;
      }
    }
    if (interfaces.size() == kMaxInterfaces) return false;
    interfaces.emplace_back(name);
    last_bus = interfaces.size() - 1;
    bus = static_cast<std::uint8_t>(last_bus);
    return true;
  }

  detail::LineOutcome parse(std::string_view line) {
    switch (parse_line(line, parsed, problem)) {
      case LineKind::Comment:
        return detail::LineOutcome::Comment;
      case LineKind::Malformed:
        return detail::LineOutcome::Malformed;
      case LineKind::Frame:
        break;
    }
    std::uint8_t bus = 0;
    if (!bus_of(parsed.iface, bus)) {
      fail(problem, parsed.iface_offset, fmt::format("more than {} interfaces", kMaxInterfaces));
      return detail::LineOutcome::Malformed;
    }
    entry.frame.bus = bus;
    return detail::LineOutcome::Frame;
  }

  detail::TextLog text;
  std::vector<std::string> interfaces;
  std::size_t last_bus = 0;
  LogEntry entry;  // parsed in place: handed out by next_entry without a copy
  ParsedLine parsed{&entry.frame, &entry.direction, {}, 0};
  Problem problem;
};

CandumpReader::CandumpReader(std::istream& in, std::string source_name, ReaderOptions options)
    : impl_(std::make_unique<Impl>(nullptr, in, std::move(source_name), std::move(options))) {}

CandumpReader::CandumpReader(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
CandumpReader::CandumpReader(CandumpReader&&) noexcept = default;
CandumpReader& CandumpReader::operator=(CandumpReader&&) noexcept = default;
CandumpReader::~CandumpReader() = default;

expected<CandumpReader, Error> CandumpReader::open(const std::filesystem::path& path,
                                                   ReaderOptions options) {
  auto impl = detail::open_text_log<Impl>(path.string(), std::move(options));
  if (!impl) return unexpected(impl.error());
  return CandumpReader(std::move(*impl));
}

expected<std::optional<LogEntry>, Error> CandumpReader::next() {
  Impl& d = *impl_;
  const auto got = d.text.next(d.problem, [&d](std::string_view line) { return d.parse(line); });
  if (!got) return unexpected(got.error());
  if (!*got) return std::optional<LogEntry>{};
  return std::optional<LogEntry>(d.entry);
}

expected<LogEntry*, Error> CandumpReader::next_entry() {
  Impl& d = *impl_;
  const auto got = d.text.next(d.problem, [&d](std::string_view line) { return d.parse(line); });
  if (!got) return unexpected(got.error());
  return *got ? &d.entry : nullptr;
}

const std::vector<std::string>& CandumpReader::interfaces() const noexcept {
  return impl_->interfaces;
}
std::uint64_t CandumpReader::malformed_count() const noexcept {
  return impl_->text.malformed_count();
}
const std::vector<ParseError>& CandumpReader::errors() const noexcept {
  return impl_->text.errors();
}
std::uint64_t CandumpReader::line_number() const noexcept { return impl_->text.line_number(); }
const std::string& CandumpReader::source_name() const noexcept { return impl_->text.source(); }

expected<CanLog, Error> read_candump_file(const std::filesystem::path& path,
                                          ReaderOptions options) {
  // The interface names are only known once the whole file is read.
  auto reader = CandumpReader::open(path, std::move(options));
  if (!reader) return unexpected(reader.error());
  auto log = detail::read_entries(*reader);
  if (log) log->interfaces = reader->interfaces();
  return log;
}

expected<Frame, Error> parse_candump_frame(std::string_view text) {
  Frame f;
  Problem p;
  if (!parse_frame(text, 0, f, p)) {
    return unexpected(Error{EINVAL, fmt::format("column {}: {}", p.offset + 1, p.message)});
  }
  return f;
}

// --- writer ------------------------------------------------------------------------------------

void write_candump_line(std::string& out, const Frame& frame, std::string_view iface,
                        std::optional<Direction> direction, CandumpWriteOptions options) {
  fmt::memory_buffer b;
  format_line(b, frame, iface, direction, options);
  out.append(b.data(), b.size());
}

void write_candump_line(std::ostream& out, const Frame& frame, std::string_view iface,
                        std::optional<Direction> direction, CandumpWriteOptions options) {
  fmt::memory_buffer b;
  format_line(b, frame, iface, direction, options);
  out.write(b.data(), static_cast<std::streamsize>(b.size()));
}

expected<void, Error> write_candump_file(const std::filesystem::path& path,
                                         std::span<const LogEntry> entries,
                                         std::span<const std::string> interfaces,
                                         CandumpWriteOptions options) {
  errno = 0;
  std::ofstream out(path, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!out.is_open()) {
    const int err = errno != 0 ? errno : EIO;
    return unexpected(
        Error{err, fmt::format("{}: cannot create: {}", path.string(), std::strerror(err))});
  }
  fmt::memory_buffer b;
  std::string fallback;
  for (const LogEntry& e : entries) {
    std::string_view name;
    if (e.frame.bus < interfaces.size()) {
      name = interfaces[e.frame.bus];
    } else {
      fallback = fmt::format("can{}", e.frame.bus);
      name = fallback;
    }
    b.clear();
    format_line(b, e.frame, name, e.direction, options);
    out.write(b.data(), static_cast<std::streamsize>(b.size()));
  }
  out.flush();
  if (!out) {
    const int err = errno != 0 ? errno : EIO;
    return unexpected(
        Error{err, fmt::format("{}: write failed: {}", path.string(), std::strerror(err))});
  }
  return {};
}

}  // namespace vigil::can
