#include "vigil/config/units.hpp"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include "vigil/config/error.hpp"

namespace vigil::config {
namespace {

// Every value is computed exactly from the decimal text: mantissa × 10^exp10, with at most 19
// significant digits so that the mantissa fits in 64 bits. Doubles would turn "0.3ms" into
// 299'999 ns.
struct Decimal {
  std::uint64_t mantissa = 0;
  int exp10 = 0;
  bool negative = false;
};

struct Unit {
  std::string_view name;
  int exp10;  // the unit is 10^exp10 nanoseconds (durations) or hertz (rates)
};

constexpr std::array kDurationUnits{Unit{"ns", 0},      Unit{"us", 3}, Unit{"\u00b5s", 3},
                                    Unit{"\u03bcs", 3}, Unit{"ms", 6}, Unit{"s", 9}};
constexpr std::array kRateUnits{Unit{"Hz", 0}, Unit{"kHz", 3}, Unit{"MHz", 6}};

constexpr std::array<std::string_view, 7> kAllUnitNames{"ns", "us", "ms", "s", "Hz", "kHz", "MHz"};
constexpr std::string_view kDurationUnitList = "ns, us, ms or s";
constexpr std::string_view kPeriodUnitList = "ns, us, ms, s, Hz, kHz or MHz";
constexpr std::string_view kRateUnitList = "Hz, kHz or MHz";
constexpr int kMaxDigits = 19;  // 10^19 - 1 < 2^64

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

// What the text holds: a number, then the unit (possibly empty) after optional blanks.
struct Quantity {
  Decimal value;
  std::string_view unit;
};

// Parses "[+-]digits[.digits][e[+-]digits] [unit]". nullopt when there is no number in front
// or it has too many significant digits.
std::optional<Quantity> split(std::string_view text) {
  Quantity q;
  std::size_t i = 0;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) {
    q.value.negative = text[i] == '-';
    ++i;
  }
  int digits = 0;  // significant digits kept in the mantissa
  bool any_digit = false;
  bool fraction = false;
  for (; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '.' && !fraction) {
      fraction = true;
      continue;
    }
    if (!is_digit(c)) break;
    any_digit = true;
    const int d = c - '0';
    if (q.value.mantissa == 0 && d == 0) {
      if (fraction) --q.value.exp10;  // leading zero after the point: 0.05
      continue;
    }
    if (digits < kMaxDigits) {
      q.value.mantissa = q.value.mantissa * 10 + static_cast<std::uint64_t>(d);
      ++digits;
      if (fraction) --q.value.exp10;
    } else if (d != 0) {
      return std::nullopt;  // more precision than 19 digits: refuse rather than round
    } else if (!fraction) {
      ++q.value.exp10;  // a dropped zero of the integer part still multiplies by 10
    }
  }
  if (!any_digit) return std::nullopt;
  // An exponent only if [eE] is followed by an optional sign and a digit; otherwise 'e' would
  // start the unit (no unit does today, but the text stays unambiguous).
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    std::size_t j = i + 1;
    bool negative_exp = false;
    if (j < text.size() && (text[j] == '+' || text[j] == '-')) {
      negative_exp = text[j] == '-';
      ++j;
    }
    if (j < text.size() && is_digit(text[j])) {
      int e = 0;
      for (; j < text.size() && is_digit(text[j]); ++j) {
        if (e < 100'000) e = e * 10 + (text[j] - '0');
      }
      q.value.exp10 += negative_exp ? -e : e;
      i = j;
    }
  }
  q.unit = trim(text.substr(i));
  return q;
}

enum class Scaled { Ok, Overflow, Fraction };

// mantissa × 10^exp10 as an integer no larger than `limit`.
Scaled scale(std::uint64_t mantissa, int exp10, std::uint64_t limit, std::uint64_t& out) {
  if (mantissa == 0) {
    out = 0;
    return Scaled::Ok;
  }
  if (exp10 >= 0) {
    for (int k = 0; k < exp10; ++k) {
      if (mantissa > limit / 10) return Scaled::Overflow;
      mantissa *= 10;
    }
    if (mantissa > limit) return Scaled::Overflow;
    out = mantissa;
    return Scaled::Ok;
  }
  if (-exp10 > kMaxDigits) return Scaled::Fraction;  // mantissa < 10^19 cannot be a multiple
  std::uint64_t divisor = 1;
  for (int k = 0; k < -exp10; ++k) divisor *= 10;
  if (mantissa % divisor != 0) return Scaled::Fraction;
  out = mantissa / divisor;
  if (out > limit) return Scaled::Overflow;
  return Scaled::Ok;
}

constexpr auto kMaxNanos = static_cast<std::uint64_t>(std::numeric_limits<Nanos>::max());

std::optional<Unit> find_unit(std::string_view name, std::span<const Unit> units) {
  for (const Unit& u : units) {
    if (u.name == name) return u;
  }
  return std::nullopt;
}

int bare_exp10(TimeUnit unit) {
  switch (unit) {
    case TimeUnit::Nanos:
      return 0;
    case TimeUnit::Micros:
      return 3;
    case TimeUnit::Millis:
      return 6;
    case TimeUnit::Seconds:
      return 9;
    case TimeUnit::None:
      break;
  }
  return 0;
}

std::string unknown_unit(std::string_view text, std::string_view unit, std::string_view list) {
  std::string message = fmt::format("'{}' has an unknown unit '{}'", text, unit);
  if (std::optional<std::string_view> hint = closest_match(unit, kAllUnitNames)) {
    return message + fmt::format("; did you mean '{}'?", *hint);
  }
  return message + fmt::format("; use {}", list);
}

expected<Nanos, std::string> duration_from(std::string_view text, const Decimal& value,
                                           int unit_exp10) {
  if (value.negative && value.mantissa != 0) {
    return vigil::unexpected<std::string>(
        fmt::format("'{}' is negative; a duration must be zero or more", text));
  }
  std::uint64_t ns = 0;
  switch (scale(value.mantissa, value.exp10 + unit_exp10, kMaxNanos, ns)) {
    case Scaled::Overflow:
      return vigil::unexpected<std::string>(
          fmt::format("'{}' is too long (the limit is about 292 years)", text));
    case Scaled::Fraction:
      return vigil::unexpected<std::string>(
          fmt::format("'{}' is not a whole number of nanoseconds", text));
    case Scaled::Ok:
      break;
  }
  return static_cast<Nanos>(ns);
}

expected<Nanos, std::string> period_from_rate(std::string_view text, const Decimal& value,
                                              int unit_exp10) {
  if (value.negative || value.mantissa == 0) {
    return vigil::unexpected<std::string>(fmt::format("'{}' is not a positive rate", text));
  }
  // period [ns] = 10^9 / (mantissa × 10^(exp10 + unit)) = 10^q / mantissa, rounded to nearest.
  const long q = 9L - value.exp10 - unit_exp10;
  const auto too_high = [&] {
    return vigil::unexpected<std::string>(
        fmt::format("'{}' is too high: its period is shorter than 1ns", text));
  };
  const auto too_low = [&] {
    return vigil::unexpected<std::string>(
        fmt::format("'{}' is too low: its period is longer than about 292 years", text));
  };
  if (q < 0) return too_high();
  std::uint64_t period = 0;
  if (q <= kMaxDigits) {
    std::uint64_t numerator = 1;
    for (long k = 0; k < q; ++k) numerator *= 10;
    // numerator <= 10^19 and mantissa / 2 < 5·10^18: the sum stays below 2^64.
    period = (numerator + value.mantissa / 2) / value.mantissa;
  } else {
    const long double p =
        std::pow(10.0L, static_cast<long double>(q)) / static_cast<long double>(value.mantissa);
    if (!(p < static_cast<long double>(kMaxNanos))) return too_low();
    period = static_cast<std::uint64_t>(std::llround(p));
  }
  if (period == 0) return too_high();
  if (period > kMaxNanos) return too_low();
  return static_cast<Nanos>(period);
}

enum class Accept { Duration, Rate, Period };

expected<Nanos, std::string> parse(std::string_view raw, Accept accept, TimeUnit bare_unit) {
  const std::string_view text = trim(raw);
  const std::string_view list = accept == Accept::Duration ? kDurationUnitList
                                : accept == Accept::Rate   ? kRateUnitList
                                                           : kPeriodUnitList;
  const std::optional<Quantity> q = split(text);
  if (!q) {
    const std::string_view example = accept == Accept::Duration ? "a duration such as '2.5ms'"
                                     : accept == Accept::Rate   ? "a rate such as '100Hz'"
                                                              : "a period such as '1ms' or '1kHz'";
    if (text.empty()) return vigil::unexpected<std::string>(fmt::format("expected {}", example));
    return vigil::unexpected<std::string>(fmt::format("expected {}, got '{}'", example, text));
  }
  if (q->unit.empty()) {
    if (accept != Accept::Rate && bare_unit != TimeUnit::None) {
      return duration_from(text, q->value, bare_exp10(bare_unit));
    }
    return vigil::unexpected<std::string>(fmt::format("'{}' has no unit; use {} (e.g. '{}{}')",
                                                      text, list, text,
                                                      accept == Accept::Rate ? "Hz" : "ms"));
  }
  if (accept != Accept::Rate) {
    if (std::optional<Unit> u = find_unit(q->unit, kDurationUnits)) {
      return duration_from(text, q->value, u->exp10);
    }
  }
  if (accept != Accept::Duration) {
    if (std::optional<Unit> u = find_unit(q->unit, kRateUnits)) {
      return period_from_rate(text, q->value, u->exp10);
    }
  }
  if (accept == Accept::Duration && find_unit(q->unit, kRateUnits)) {
    return vigil::unexpected<std::string>(
        fmt::format("'{}' is a rate; a duration is expected here (use {})", text, list));
  }
  if (accept == Accept::Rate && find_unit(q->unit, kDurationUnits)) {
    return vigil::unexpected<std::string>(
        fmt::format("'{}' is a duration; a rate is expected here (use {})", text, list));
  }
  return vigil::unexpected<std::string>(unknown_unit(text, q->unit, list));
}

}  // namespace

expected<Nanos, std::string> parse_duration(std::string_view text, TimeUnit bare_unit) {
  return parse(text, Accept::Duration, bare_unit);
}

expected<Nanos, std::string> parse_rate_as_period(std::string_view text) {
  return parse(text, Accept::Rate, TimeUnit::None);
}

expected<Nanos, std::string> parse_period(std::string_view text, TimeUnit bare_unit) {
  return parse(text, Accept::Period, bare_unit);
}

std::string format_duration(Nanos ns) {
  if (ns == 0) return "0ns";
  std::string out = ns < 0 ? "-" : "";
  // -(ns + 1) + 1 avoids negating INT64_MIN.
  const std::uint64_t v =
      ns < 0 ? static_cast<std::uint64_t>(-(ns + 1)) + 1 : static_cast<std::uint64_t>(ns);
  struct Scale {
    std::uint64_t factor;
    int digits;
    std::string_view name;
  };
  constexpr std::array kScales{Scale{1'000'000'000, 9, "s"}, Scale{1'000'000, 6, "ms"},
                               Scale{1'000, 3, "us"}, Scale{1, 0, "ns"}};
  for (const Scale& s : kScales) {
    if (v < s.factor) continue;
    out += fmt::format("{}", v / s.factor);
    if (const std::uint64_t rest = v % s.factor; rest != 0) {
      std::string fraction = fmt::format("{:0{}}", rest, s.digits);
      while (fraction.back() == '0') fraction.pop_back();
      out += '.';
      out += fraction;
    }
    out += s.name;
    break;
  }
  return out;
}

}  // namespace vigil::config
