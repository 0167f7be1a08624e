// PEAK-System trace files (.trc), versions 1.0-1.3, 2.0 and 2.1 ("PEAK CAN TRC File Format").
#include "vigil/can/log/trc.hpp"

#include <fmt/format.h>

#include <array>
#include <cerrno>
#include <istream>
#include <optional>
#include <utility>

#include "can/log/line_reader.hpp"

namespace vigil::can {

const char* to_string(TrcVersion v) noexcept {
  switch (v) {
    case TrcVersion::V1_0:
      return "1.0";
    case TrcVersion::V1_1:
      return "1.1";
    case TrcVersion::V1_2:
      return "1.2";
    case TrcVersion::V1_3:
      return "1.3";
    case TrcVersion::V2_0:
      return "2.0";
    case TrcVersion::V2_1:
      return "2.1";
  }
  return "?";
}

namespace {

using detail::hex_value;
using detail::is_blank;
using detail::is_digit;
using detail::Problem;

// Days from 1899-12-30 (the OLE Automation date epoch of $STARTTIME) to 1970-01-01.
constexpr std::int64_t kOleDaysToUnixEpoch = 25569;
constexpr std::int64_t kNanosPerDay = 86'400 * kNanosPerSecond;

// A column of a record line ($COLUMNS letters in brackets).
enum class Col : std::uint8_t {
  Number,    // [N] message number; "12)" in version 1.x
  Offset,    // [O] time offset in ms
  Type,      // [T] record type
  Bus,       // [B] bus number, 1-based
  Id,        // [I] identifier, hex
  Dir,       // [d] Rx / Tx
  Reserved,  // [R] reserved, "-"
  Length,    // [l] data length in bytes
  Dlc,       // [L] data length code
  Data,      // [D] data bytes, the rest of the line
};
constexpr std::size_t kColKinds = 10;

const char* col_name(Col c) {
  switch (c) {
    case Col::Number:
      return "message number";
    case Col::Offset:
      return "time offset";
    case Col::Type:
      return "type";
    case Col::Bus:
      return "bus";
    case Col::Id:
      return "identifier";
    case Col::Dir:
      return "direction";
    case Col::Reserved:
      return "reserved";
    case Col::Length:
      return "data length";
    case Col::Dlc:
      return "DLC";
    case Col::Data:
      return "data";
  }
  return "?";
}

struct Layout {
  std::array<Col, kColKinds> cols{};
  std::size_t count = 0;               // columns, Data included (always last)
  std::array<int, kColKinds> index{};  // position of each column kind, -1 if absent
  bool v1 = false;                     // "N)" numbers and v1 type words

  [[nodiscard]] int at(Col c) const { return index[static_cast<std::size_t>(c)]; }
  [[nodiscard]] bool has(Col c) const { return at(c) >= 0; }
  [[nodiscard]] std::size_t fixed() const { return count - 1; }  // columns before Data
};

Layout make_layout(std::initializer_list<Col> cols, bool v1) {
  Layout l;
  l.index.fill(-1);
  l.v1 = v1;
  for (Col c : cols) {
    l.index[static_cast<std::size_t>(c)] = static_cast<int>(l.count);
    l.cols[l.count++] = c;
  }
  return l;
}

Layout default_layout(TrcVersion v) {
  using enum Col;
  switch (v) {
    case TrcVersion::V1_0:
      return make_layout({Number, Offset, Id, Dlc, Data}, true);
    case TrcVersion::V1_1:
      return make_layout({Number, Offset, Type, Id, Dlc, Data}, true);
    case TrcVersion::V1_2:
      return make_layout({Number, Offset, Bus, Type, Id, Dlc, Data}, true);
    case TrcVersion::V1_3:
      return make_layout({Number, Offset, Bus, Type, Id, Reserved, Dlc, Data}, true);
    case TrcVersion::V2_0:
      return make_layout({Number, Offset, Type, Id, Dir, Length, Data}, false);
    case TrcVersion::V2_1:
      return make_layout({Number, Offset, Type, Bus, Id, Dir, Reserved, Dlc, Data}, false);
  }
  return {};
}

// Parses a $COLUMNS value ("N,O,T,B,I,d,R,L,D"); on failure `p` says why.
bool parse_columns(std::string_view s, std::size_t base, Layout& out, Problem& p) {
  std::array<Col, kColKinds> cols{};
  std::size_t count = 0;
  std::array<bool, kColKinds> seen{};
  std::size_t pos = 0;
  while (pos < s.size() && is_blank(s[pos])) ++pos;
  for (;;) {
    if (pos >= s.size()) {
      p = {base + pos, "$COLUMNS: expected a column letter"};
      return false;
    }
    Col c{};
    switch (s[pos]) {
      case 'N':
        c = Col::Number;
        break;
      case 'O':
        c = Col::Offset;
        break;
      case 'T':
        c = Col::Type;
        break;
      case 'B':
        c = Col::Bus;
        break;
      case 'I':
        c = Col::Id;
        break;
      case 'd':
        c = Col::Dir;
        break;
      case 'R':
        c = Col::Reserved;
        break;
      case 'l':
        c = Col::Length;
        break;
      case 'L':
        c = Col::Dlc;
        break;
      case 'D':
        c = Col::Data;
        break;
      default:
        p = {base + pos, fmt::format("$COLUMNS: unknown column '{}'", s[pos])};
        return false;
    }
    if (seen[static_cast<std::size_t>(c)]) {
      p = {base + pos, fmt::format("$COLUMNS: column '{}' appears twice", s[pos])};
      return false;
    }
    seen[static_cast<std::size_t>(c)] = true;
    cols[count++] = c;
    ++pos;
    while (pos < s.size() && is_blank(s[pos])) ++pos;
    if (pos >= s.size()) break;
    if (s[pos] != ',') {
      p = {base + pos, "$COLUMNS: expected ',' between column letters"};
      return false;
    }
    ++pos;
    while (pos < s.size() && is_blank(s[pos])) ++pos;
  }
  const auto has = [&](Col c) { return seen[static_cast<std::size_t>(c)]; };
  if (!has(Col::Offset) || !has(Col::Type) || !has(Col::Id) || !has(Col::Data) ||
      (!has(Col::Length) && !has(Col::Dlc))) {
    p = {base, "$COLUMNS must name at least O, T, I, D and L or l"};
    return false;
  }
  if (has(Col::Length) && has(Col::Dlc)) {
    p = {base, "$COLUMNS names both L (DLC) and l (data length)"};
    return false;
  }
  if (cols[count - 1] != Col::Data) {
    p = {base, "$COLUMNS: D (data) must be the last column"};
    return false;
  }
  out = make_layout({}, false);
  for (std::size_t i = 0; i < count; ++i) {
    out.index[static_cast<std::size_t>(cols[i])] = static_cast<int>(i);
    out.cols[i] = cols[i];
  }
  out.count = count;
  return true;
}

// Whitespace-separated fields of one line, without allocation.
struct Tokens {
  static constexpr std::size_t kMax = 96;  // 9 columns + 64 data bytes, with room to spare
  std::array<std::string_view, kMax> tok;
  std::size_t count = 0;
  bool overflow = false;

  void split(std::string_view line) {
    count = 0;
    overflow = false;
    std::size_t pos = 0;
    const std::size_t n = line.size();
    for (;;) {
      while (pos < n && is_blank(line[pos])) ++pos;
      if (pos >= n) return;
      const std::size_t start = pos;
      while (pos < n && !is_blank(line[pos])) ++pos;
      if (count == kMax) {
        overflow = true;
        return;
      }
      tok[count++] = line.substr(start, pos - start);
    }
  }
};

enum class Kind : std::uint8_t { Data, Fd, Remote, ErrorFrame, Skip, Unknown };

struct TypeInfo {
  Kind kind = Kind::Unknown;
  bool brs = false;
  bool esi = false;
  std::optional<Direction> direction;  // version 1 types Rx/Tx
};

TypeInfo type_of(Kind kind, bool brs = false, bool esi = false,
                 std::optional<Direction> direction = std::nullopt) {
  TypeInfo t;
  t.kind = kind;
  t.brs = brs;
  t.esi = esi;
  t.direction = direction;
  return t;
}

TypeInfo classify(std::string_view t, bool v1) {
  if (v1) {
    if (t == "Rx") return type_of(Kind::Data, false, false, Direction::Rx);
    if (t == "Tx") return type_of(Kind::Data, false, false, Direction::Tx);
    if (t == "Warng") return type_of(Kind::Skip);
    if (t == "Error") return type_of(Kind::ErrorFrame);
    return type_of(Kind::Unknown);
  }
  if (t.size() != 2) return type_of(Kind::Unknown);
  if (t == "DT") return type_of(Kind::Data);
  if (t == "FD") return type_of(Kind::Fd);
  if (t == "FB") return type_of(Kind::Fd, true, false);
  if (t == "FE") return type_of(Kind::Fd, false, true);
  if (t == "BI") return type_of(Kind::Fd, true, true);
  if (t == "RR") return type_of(Kind::Remote);
  if (t == "ER") return type_of(Kind::ErrorFrame);
  if (t == "ST" || t == "EC" || t == "EV") return type_of(Kind::Skip);
  return type_of(Kind::Unknown);
}

std::optional<Direction> parse_dir(std::string_view t) {
  if (t == "Rx") return Direction::Rx;
  if (t == "Tx") return Direction::Tx;
  return std::nullopt;
}

bool parse_uint(std::string_view t, std::uint32_t max, std::uint32_t& out) {
  if (t.empty() || t.size() > 9) return false;
  std::uint32_t v = 0;
  for (char c : t) {
    if (!is_digit(c)) return false;
    v = v * 10 + static_cast<std::uint32_t>(c - '0');
  }
  if (v > max) return false;
  out = v;
  return true;
}

bool is_hex_byte(std::string_view t) {
  return t.size() == 2 && hex_value(t[0]) <= 0xF && hex_value(t[1]) <= 0xF;
}

std::uint8_t hex_byte(std::string_view t) {
  return static_cast<std::uint8_t>((hex_value(t[0]) << 4) | hex_value(t[1]));
}

// Milliseconds with up to 6 decimals ("1059.9", "17535.400") -> exact nanoseconds.
bool parse_offset(std::string_view t, Nanos& out, std::string& why) {
  std::size_t pos = 0;
  std::int64_t ms = 0;
  while (pos < t.size() && is_digit(t[pos])) {
    if (!detail::mul_add(ms, 10, t[pos] - '0', ms)) {
      why = "time offset out of range";
      return false;
    }
    ++pos;
  }
  if (pos == 0) {
    why = fmt::format("time offset '{}' is not a number of milliseconds", t);
    return false;
  }
  std::int64_t frac = 0;
  std::size_t digits = 0;
  if (pos < t.size() && t[pos] == '.') {
    ++pos;
    while (pos < t.size() && is_digit(t[pos])) {
      if (digits == 6) {
        why = "time offset has more than 6 decimals (the resolution is 1 ns)";
        return false;
      }
      frac = frac * 10 + (t[pos] - '0');
      ++digits;
      ++pos;
    }
  }
  if (pos != t.size()) {
    why = fmt::format("time offset '{}' is not a number of milliseconds", t);
    return false;
  }
  if (!detail::mul_add(ms, kNanosPerMilli, frac * detail::kPow10[6 - digits], out)) {
    why = "time offset out of range";
    return false;
  }
  return true;
}

// $STARTTIME: days since 1899-12-30 as a decimal fraction -> ns since the Unix epoch, rounded.
bool parse_start_time(std::string_view s, Nanos& out) {
  __extension__ typedef __int128 Int128;  // exact product of an 18-digit fraction and ns/day
  std::size_t pos = 0;
  while (pos < s.size() && is_blank(s[pos])) ++pos;
  std::int64_t days = 0;
  const std::size_t days_start = pos;
  while (pos < s.size() && is_digit(s[pos])) {
    if (!detail::mul_add(days, 10, s[pos] - '0', days)) return false;
    ++pos;
  }
  if (pos == days_start) return false;
  std::int64_t frac = 0;
  std::size_t digits = 0;
  if (pos < s.size() && s[pos] == '.') {
    ++pos;
    while (pos < s.size() && is_digit(s[pos])) {
      if (digits < 18) {  // further digits are below 10^-18 day, i.e. 0.0000864 ns
        frac = frac * 10 + (s[pos] - '0');
        ++digits;
      }
      ++pos;
    }
  }
  while (pos < s.size() && is_blank(s[pos])) ++pos;
  if (pos != s.size()) return false;
  std::int64_t whole = 0;
  if (!detail::mul_add(days - kOleDaysToUnixEpoch, kNanosPerDay, 0, whole)) return false;
  const Int128 scale = detail::kPow10[digits];
  const auto part = static_cast<std::int64_t>((Int128{frac} * kNanosPerDay + scale / 2) / scale);
  return !__builtin_add_overflow(whole, part, &out);
}

// Why `tok` is not a message number ("12", in version 1 "12)"); null when it is one.
const char* number_error(std::string_view tok, bool v1) {
  std::string_view digits = tok;
  if (v1) {
    if (tok.size() < 2 || tok.back() != ')') return "message number must be digits followed by ')'";
    digits.remove_suffix(1);
  }
  if (digits.empty() || digits.find_first_not_of("0123456789") != std::string_view::npos) {
    return v1 ? "message number must be digits followed by ')'" : "message number must be digits";
  }
  return nullptr;
}

// A bus column ("1" to "256", or "-": none) into the 0-based `bus`; false when it is neither.
bool parse_bus(std::string_view t, std::uint8_t& bus) {
  if (t == "-") return true;
  std::uint32_t v = 0;
  if (!parse_uint(t, 256, v) || v == 0) return false;
  bus = static_cast<std::uint8_t>(v - 1);
  return true;
}

// What the fixed columns of a record give besides the frame's own fields.
struct ColumnValues {
  Nanos offset = 0;         // the O column
  std::uint32_t size = 0;   // the L or l column
  std::size_t size_at = 0;  // where it is in the line
};

using Outcome = detail::LineOutcome;

}  // namespace

// --- reader ------------------------------------------------------------------------------------

struct TrcReader::Impl {
  Impl(std::unique_ptr<std::istream> owned, std::istream& in, std::string source,
       ReaderOptions options)
      : text(std::move(owned), in, std::move(source), std::move(options)) {}

  Outcome parse(std::string_view line);

  Outcome header_line(std::string_view line, std::size_t semicolon);
  Outcome start_records();
  Outcome record(std::string_view line);
  Outcome error_record(std::string_view line);

  // The steps of `record`, by group of fields; those that return an optional return an outcome
  // when the line ends there (a malformed field, a status line).
  std::optional<Outcome> record_type(std::string_view line, TypeInfo& type);
  std::optional<Outcome> fixed_columns(std::string_view line, const TypeInfo& type,
                                       ColumnValues& cols);
  std::optional<Outcome> identifier(std::string_view tok, std::size_t at, const TypeInfo& type);
  Outcome payload(std::string_view line, const TypeInfo& type, const ColumnValues& cols);
  Outcome data_frame(std::string_view line, Kind kind, const TypeInfo& type,
                     const ColumnValues& cols, std::size_t data_at);
  Outcome remote_frame(const ColumnValues& cols, std::size_t given, std::size_t data_at);
  Outcome v1_error_frame(std::string_view line, const ColumnValues& cols, std::size_t first,
                         std::size_t data_at);
  std::optional<Outcome> data_bytes(std::string_view line, std::size_t first, std::size_t n,
                                    std::size_t to);

  Outcome malformed(std::size_t offset, std::string message) {
    problem.offset = offset;
    problem.message = std::move(message);
    return Outcome::Malformed;
  }
  std::size_t offset_of(std::string_view line, std::string_view token) const {
    return static_cast<std::size_t>(token.data() - line.data());
  }
  bool timestamp(Nanos offset, Nanos& out) const {
    if (!start) {
      out = offset;
      return true;
    }
    return !__builtin_add_overflow(*start, offset, &out);
  }

  detail::TextLog text;

  TrcVersion version = TrcVersion::V1_0;
  std::optional<Nanos> start;
  std::string columns;  // $COLUMNS value, resolved at the first record
  std::uint64_t columns_line = 0;
  std::size_t columns_offset = 0;
  bool in_records = false;
  Layout layout;

  Tokens tokens;
  Problem problem;
  LogEntry entry;
};

Outcome TrcReader::Impl::header_line(std::string_view line, std::size_t semicolon) {
  // ";$KEY=VALUE" lines are the header while no record has been read; the rest are comments.
  if (in_records || semicolon + 1 >= line.size() || line[semicolon + 1] != '$') {
    return Outcome::Comment;
  }
  const std::size_t eq = line.find('=', semicolon);
  if (eq == std::string_view::npos) return Outcome::Comment;
  const std::string_view key = line.substr(semicolon + 2, eq - semicolon - 2);
  const std::string_view value = line.substr(eq + 1);
  if (key == "FILEVERSION") {
    std::size_t b = 0;
    std::size_t e = value.size();
    while (b < e && is_blank(value[b])) ++b;
    while (e > b && is_blank(value[e - 1])) --e;
    const std::string_view v = value.substr(b, e - b);
    if (v == "1.0") {
      version = TrcVersion::V1_0;
    } else if (v == "1.1") {
      version = TrcVersion::V1_1;
    } else if (v == "1.2") {
      version = TrcVersion::V1_2;
    } else if (v == "1.3") {
      version = TrcVersion::V1_3;
    } else if (v == "2.0") {
      version = TrcVersion::V2_0;
    } else if (v == "2.1") {
      version = TrcVersion::V2_1;
    } else {
      problem.offset = eq + 1 + b;
      problem.message =
          fmt::format("unsupported $FILEVERSION '{}' (1.0 to 1.3, 2.0 and 2.1 are supported)", v);
      return Outcome::Fatal;
    }
    return Outcome::Comment;
  }
  if (key == "STARTTIME") {
    Nanos t = 0;
    if (!parse_start_time(value, t)) {
      return malformed(eq + 1, fmt::format("$STARTTIME '{}' is not a number of days", value));
    }
    start = t;
    return Outcome::Comment;
  }
  if (key == "COLUMNS") {
    columns.assign(value);
    columns_line = text.line_number();
    columns_offset = eq + 1;
    return Outcome::Comment;
  }
  return Outcome::Comment;  // unknown keys are comments, as PEAK's tools treat them
}

Outcome TrcReader::Impl::start_records() {
  in_records = true;
  layout = default_layout(version);
  if (version >= TrcVersion::V2_0 && !columns.empty()) {
    if (!parse_columns(columns, columns_offset, layout, problem)) {
      problem.message += fmt::format(" (line {})", columns_line);
      return Outcome::Fatal;
    }
  }
  return Outcome::Comment;
}

Outcome TrcReader::Impl::error_record(std::string_view line) {
  // v2 error frame "ER": version 2.1 writes every column ('-' for the missing id and reserved),
  // version 2.0 leaves the id and length columns blank, so its fields are found by their order:
  // number, offset, type, direction, then the data bytes.
  const Tokens& t = tokens;
  const int dir_at = layout.at(Col::Dir);
  std::size_t data_from = 0;
  std::optional<Direction> dir;
  std::uint8_t bus = 0;
  if (dir_at >= 0 && t.count >= layout.fixed() &&
      parse_dir(t.tok[static_cast<std::size_t>(dir_at)])) {
    dir = parse_dir(t.tok[static_cast<std::size_t>(dir_at)]);
    data_from = layout.fixed();
    if (layout.has(Col::Bus)) {
      const std::string_view b = t.tok[static_cast<std::size_t>(layout.at(Col::Bus))];
      std::uint32_t v = 0;
      if (b != "-") {
        if (!parse_uint(b, 256, v) || v == 0) {
          return malformed(offset_of(line, b), fmt::format("bus '{}' is not a number 1-256", b));
        }
        bus = static_cast<std::uint8_t>(v - 1);
      }
    }
  } else {
    std::size_t i = static_cast<std::size_t>(layout.at(Col::Type)) + 1;
    while (i < t.count && !parse_dir(t.tok[i])) ++i;
    if (i >= t.count) return malformed(line.size(), "error record without a direction (Rx/Tx)");
    dir = parse_dir(t.tok[i]);
    data_from = i + 1;
  }
  const auto offset_at = static_cast<std::size_t>(layout.at(Col::Offset));
  if (offset_at >= t.count) return malformed(line.size(), "missing time offset column");
  Nanos offset = 0;
  const std::string_view o = t.tok[offset_at];
  if (std::string why; !parse_offset(o, offset, why)) return malformed(offset_of(line, o), why);
  Frame& f = entry.frame;
  f = Frame{};
  f.error = true;
  f.bus = bus;
  if (!timestamp(offset, f.timestamp))
    return malformed(offset_of(line, o), "timestamp out of range");
  std::size_t n = 0;
  for (std::size_t i = data_from; i < t.count; ++i) {
    if (!is_hex_byte(t.tok[i])) {
      return malformed(offset_of(line, t.tok[i]),
                       fmt::format("'{}' is not a data byte (two hex digits)", t.tok[i]));
    }
    if (n == kMaxClassicDataLength) {
      return malformed(offset_of(line, t.tok[i]), "error record with more than 8 data bytes");
    }
    f.data[n++] = hex_byte(t.tok[i]);
  }
  f.length = static_cast<std::uint8_t>(n);
  entry.direction = dir;
  return Outcome::Frame;
}

Outcome TrcReader::Impl::record(std::string_view line) {
  tokens.split(line);
  if (tokens.count == 0) return Outcome::Comment;

  TypeInfo type = type_of(Kind::Data);
  if (const auto o = record_type(line, type)) return *o;
  if (type.kind == Kind::Skip) return Outcome::Skipped;
  if (type.kind == Kind::ErrorFrame && !layout.v1) return error_record(line);
  if (tokens.overflow) return malformed(line.size(), "too many fields");

  entry.frame = Frame{};
  entry.direction = type.direction;
  ColumnValues cols;
  if (const auto o = fixed_columns(line, type, cols)) return *o;
  return payload(line, type, cols);
}

// The T column: what the record is.
std::optional<Outcome> TrcReader::Impl::record_type(std::string_view line, TypeInfo& type) {
  if (!layout.has(Col::Type)) return std::nullopt;
  const auto at = static_cast<std::size_t>(layout.at(Col::Type));
  if (tokens.count <= at) return malformed(line.size(), "missing type column");
  type = classify(tokens.tok[at], layout.v1);
  if (type.kind == Kind::Unknown) {
    return malformed(offset_of(line, tokens.tok[at]),
                     fmt::format("unknown record type '{}'", tokens.tok[at]));
  }
  return std::nullopt;
}

// The columns before the data (number, offset, bus, id, direction, size), then the timestamp.
std::optional<Outcome> TrcReader::Impl::fixed_columns(std::string_view line, const TypeInfo& type,
                                                      ColumnValues& cols) {
  Frame& f = entry.frame;
  const Tokens& t = tokens;
  const std::size_t fixed = layout.fixed();
  for (std::size_t i = 0; i < fixed; ++i) {
    const Col c = layout.cols[i];
    if (i >= t.count) {
      return malformed(line.size(), fmt::format("missing {} column", col_name(c)));
    }
    const std::string_view tok = t.tok[i];
    const std::size_t at = offset_of(line, tok);
    switch (c) {
      case Col::Number:
        if (const char* why = number_error(tok, layout.v1)) return malformed(at, why);
        break;
      case Col::Offset:
        if (std::string why; !parse_offset(tok, cols.offset, why)) return malformed(at, why);
        break;
      case Col::Bus:
        if (!parse_bus(tok, f.bus)) {
          return malformed(at, fmt::format("bus '{}' is not a number 1-256", tok));
        }
        break;
      case Col::Id:
        if (const auto o = identifier(tok, at, type)) return o;
        break;
      case Col::Dir: {
        const auto d = parse_dir(tok);
        if (!d) return malformed(at, fmt::format("direction '{}' must be Rx or Tx", tok));
        entry.direction = d;
        break;
      }
      case Col::Length:
        cols.size_at = at;
        if (!parse_uint(tok, 64, cols.size)) {
          return malformed(at, fmt::format("data length '{}' is not a number 0-64", tok));
        }
        break;
      case Col::Dlc:
        cols.size_at = at;
        if (!parse_uint(tok, kMaxDlc, cols.size)) {
          return malformed(at, fmt::format("DLC '{}' is not a number 0-15", tok));
        }
        break;
      case Col::Type:
      case Col::Reserved:
      case Col::Data:
        break;
    }
  }
  if (!timestamp(cols.offset, f.timestamp)) {
    return malformed(offset_of(line, tokens.tok[static_cast<std::size_t>(layout.at(Col::Offset))]),
                     "timestamp out of range");
  }
  return std::nullopt;
}

// The I column: 1 to 4 hex digits for a standard id, 5 to 8 for an extended one.
std::optional<Outcome> TrcReader::Impl::identifier(std::string_view tok, std::size_t at,
                                                   const TypeInfo& type) {
  Frame& f = entry.frame;
  if (layout.cols[0] == Col::Number && !layout.has(Col::Type) && tok == "FFFFFFFF") {
    return Outcome::Skipped;  // version 1.0 bus status ("error warning") line
  }
  if (tok.empty() || tok.size() > 8) {
    return malformed(at, fmt::format("identifier '{}' must have 1 to 8 hex digits", tok));
  }
  std::uint32_t id = 0;
  for (char ch : tok) {
    const std::uint8_t v = hex_value(ch);
    if (v > 0xF) return malformed(at, fmt::format("identifier '{}' is not hexadecimal", tok));
    id = (id << 4) | v;
  }
  f.extended = tok.size() > 4;
  if (type.kind != Kind::ErrorFrame && id > (f.extended ? kMaxExtendedId : kMaxStandardId)) {
    return malformed(at,
                     fmt::format("identifier {} exceeds {}", tok, f.extended ? "1FFFFFFF" : "7FF"));
  }
  f.id = id;
  return std::nullopt;
}

// The data column, by kind of record.
Outcome TrcReader::Impl::payload(std::string_view line, const TypeInfo& type,
                                 const ColumnValues& cols) {
  const Tokens& t = tokens;
  std::size_t first = layout.fixed();
  const std::size_t given = t.count - first;
  const std::size_t data_at = given > 0 ? offset_of(line, t.tok[first]) : line.size();

  // Version 1 marks remote frames and (1.0) error frames in the data column.
  Kind kind = type.kind;
  if (layout.v1 && given > 0) {
    if (t.tok[first] == "RTR") {
      kind = Kind::Remote;
    } else if (t.tok[first] == "ERROR" && kind == Kind::Data && !layout.has(Col::Type)) {
      kind = Kind::ErrorFrame;
      ++first;
    }
  }
  switch (kind) {
    case Kind::Data:
    case Kind::Fd:
      return data_frame(line, kind, type, cols, data_at);
    case Kind::Remote:
      return remote_frame(cols, given, data_at);
    case Kind::ErrorFrame:
      return v1_error_frame(line, cols, first, data_at);
    case Kind::Skip:
    case Kind::Unknown:
      break;
  }
  return Outcome::Skipped;
}

// A data frame (Classical CAN or CAN FD): its length, then its bytes.
Outcome TrcReader::Impl::data_frame(std::string_view line, Kind kind, const TypeInfo& type,
                                    const ColumnValues& cols, std::size_t data_at) {
  Frame& f = entry.frame;
  const bool by_dlc = layout.has(Col::Dlc);
  std::size_t expect = 0;
  if (kind == Kind::Data) {
    if (!by_dlc && cols.size > kMaxClassicDataLength) {
      return malformed(
          cols.size_at,
          fmt::format("data length {} exceeds 8 for a Classical CAN frame", cols.size));
    }
    f.length = static_cast<std::uint8_t>(cols.size);
    expect = f.data_size();
  } else {
    f.fd = true;
    f.brs = type.brs;
    f.esi = type.esi;
    if (by_dlc) {
      f.length = dlc_to_length(static_cast<std::uint8_t>(cols.size));
    } else if (is_fd_length(cols.size)) {
      f.length = static_cast<std::uint8_t>(cols.size);
    } else {
      return malformed(cols.size_at,
                       fmt::format("data length {} is not a CAN FD length (0-8, 12, 16, "
                                   "20, 24, 32, 48, 64)",
                                   cols.size));
    }
    expect = f.length;
  }
  const std::size_t first = layout.fixed();
  const std::size_t given = tokens.count - first;
  if (given != expect) {
    return malformed(data_at, fmt::format("expected {} data bytes, found {}", expect, given));
  }
  if (const auto o = data_bytes(line, first, expect, 0)) return *o;
  return Outcome::Frame;
}

// A remote frame: a length and no data.
Outcome TrcReader::Impl::remote_frame(const ColumnValues& cols, std::size_t given,
                                      std::size_t data_at) {
  Frame& f = entry.frame;
  if (!layout.has(Col::Dlc) && cols.size > kMaxClassicDataLength) {
    return malformed(cols.size_at,
                     fmt::format("data length {} exceeds 8 for a remote frame", cols.size));
  }
  f.rtr = true;
  f.length = static_cast<std::uint8_t>(cols.size);
  // Version 1 writes "RTR" as the data; version 2 nothing (a lone "RTR" is accepted too).
  const bool marker = given == 1 && tokens.tok[layout.fixed()] == "RTR";
  if (given != 0 && !marker) return malformed(data_at, "a remote frame carries no data bytes");
  return Outcome::Frame;
}

Outcome TrcReader::Impl::v1_error_frame(std::string_view line, const ColumnValues& cols,
                                        std::size_t first, std::size_t data_at) {
  // Version 1 error record: the id column holds the error type, the data column the
  // direction, position and counters; keep PEAK's bytes in that order.
  Frame& f = entry.frame;
  const std::size_t n = tokens.count - first;
  if (n != cols.size) {
    return malformed(data_at, fmt::format("expected {} data bytes, found {}", cols.size, n));
  }
  if (n + 1 > kMaxClassicDataLength) {
    return malformed(data_at, "error record with more than 7 data bytes");
  }
  const std::uint32_t code = f.id;
  f.id = 0;
  f.extended = false;
  f.error = true;
  f.data[0] = static_cast<std::uint8_t>(code & 0xFF);
  if (const auto o = data_bytes(line, first, n, 1)) return *o;
  f.length = static_cast<std::uint8_t>(n + 1);
  return Outcome::Frame;
}

// `n` data bytes, from token `first` on, into the frame's data from byte `to` on. Inline: it runs
// for every frame, and GCC 12 leaves it out of line otherwise.
inline std::optional<Outcome> TrcReader::Impl::data_bytes(std::string_view line, std::size_t first,
                                                          std::size_t n, std::size_t to) {
  for (std::size_t i = 0; i < n; ++i) {
    const std::string_view tok = tokens.tok[first + i];
    if (!is_hex_byte(tok)) {
      return malformed(offset_of(line, tok),
                       fmt::format("'{}' is not a data byte (two hex digits)", tok));
    }
    entry.frame.data[to + i] = hex_byte(tok);
  }
  return std::nullopt;
}

Outcome TrcReader::Impl::parse(std::string_view line) {
  std::size_t first = 0;
  while (first < line.size() && is_blank(line[first])) ++first;
  if (first == line.size()) return Outcome::Comment;
  if (line[first] == ';') return header_line(line, first);
  if (!in_records) {
    if (const Outcome o = start_records(); o == Outcome::Fatal) return o;
  }
  return record(line);
}

TrcReader::TrcReader(std::istream& in, std::string source_name, ReaderOptions options)
    : impl_(std::make_unique<Impl>(nullptr, in, std::move(source_name), std::move(options))) {}

TrcReader::TrcReader(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
TrcReader::TrcReader(TrcReader&&) noexcept = default;
TrcReader& TrcReader::operator=(TrcReader&&) noexcept = default;
TrcReader::~TrcReader() = default;

expected<TrcReader, Error> TrcReader::open(const std::filesystem::path& path,
                                           ReaderOptions options) {
  auto impl = detail::open_text_log<Impl>(path.string(), std::move(options));
  if (!impl) return unexpected(impl.error());
  return TrcReader(std::move(*impl));
}

expected<std::optional<LogEntry>, Error> TrcReader::next() {
  Impl& d = *impl_;
  const auto got = d.text.next(d.problem, [&d](std::string_view line) { return d.parse(line); });
  if (!got) return unexpected(got.error());
  if (!*got) return std::optional<LogEntry>{};
  return std::optional<LogEntry>(d.entry);
}

expected<LogEntry*, Error> TrcReader::next_entry() {
  Impl& d = *impl_;
  const auto got = d.text.next(d.problem, [&d](std::string_view line) { return d.parse(line); });
  if (!got) return unexpected(got.error());
  return *got ? &d.entry : nullptr;
}

TrcVersion TrcReader::version() const noexcept { return impl_->version; }
std::optional<Nanos> TrcReader::start_time() const noexcept { return impl_->start; }
std::uint64_t TrcReader::malformed_count() const noexcept { return impl_->text.malformed_count(); }
std::uint64_t TrcReader::skipped_count() const noexcept { return impl_->text.skipped_count(); }
const std::vector<ParseError>& TrcReader::errors() const noexcept { return impl_->text.errors(); }
std::uint64_t TrcReader::line_number() const noexcept { return impl_->text.line_number(); }
const std::string& TrcReader::source_name() const noexcept { return impl_->text.source(); }

expected<CanLog, Error> read_trc_file(const std::filesystem::path& path, ReaderOptions options) {
  auto reader = TrcReader::open(path, std::move(options));
  if (!reader) return unexpected(reader.error());
  auto log = detail::read_entries(*reader);
  if (log) log->skipped = reader->skipped_count();
  return log;
}

}  // namespace vigil::can
