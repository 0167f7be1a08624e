#include "vigil/config/units.hpp"

#include <catch2/catch.hpp>
#include <string>

using namespace vigil::config;
using vigil::kNanosPerMicro;
using vigil::kNanosPerMilli;
using vigil::kNanosPerSecond;
using vigil::Nanos;

namespace {
// The error message of a parse that must fail.
template <class R>
std::string error_of(const R& r) {
  REQUIRE_FALSE(r.has_value());
  return r.error();
}
}  // namespace

TEST_CASE("Durations parse exactly with every unit", "[config][units]") {
  CHECK(parse_duration("10ns") == 10);
  CHECK(parse_duration("500us") == 500 * kNanosPerMicro);
  CHECK(parse_duration("500\u00b5s") == 500 * kNanosPerMicro);  // micro sign
  CHECK(parse_duration("500\u03bcs") == 500 * kNanosPerMicro);  // Greek mu
  CHECK(parse_duration("1ms") == kNanosPerMilli);
  CHECK(parse_duration("2.5 s") == 2'500'000'000);
  CHECK(parse_duration("3s") == 3 * kNanosPerSecond);
  CHECK(parse_duration("0ms") == 0);
  CHECK(parse_duration("+7 us") == 7'000);
  CHECK(parse_duration("\t1.25\tms ") == 1'250'000);
}

TEST_CASE("Decimal durations are exact, not rounded through a double", "[config][units]") {
  CHECK(parse_duration("0.3ms") == 300'000);
  CHECK(parse_duration("0.1s") == 100'000'000);
  CHECK(parse_duration(".5us") == 500);
  CHECK(parse_duration("1e-3 s") == kNanosPerMilli);
  CHECK(parse_duration("1.5e3ns") == 1'500);
  CHECK(parse_duration("9223372036.854775807s") == INT64_MAX);
  CHECK(parse_duration("1.000000000000000000000ms") == kNanosPerMilli);  // trailing zeros
}

TEST_CASE("A duration that is not a whole number of nanoseconds is an error", "[config][units]") {
  CHECK(error_of(parse_duration("1.5ns")) == "'1.5ns' is not a whole number of nanoseconds");
  CHECK(error_of(parse_duration("0.0001us")) == "'0.0001us' is not a whole number of nanoseconds");
}

TEST_CASE("Unknown duration units are reported with a hint or the list", "[config][units]") {
  CHECK(error_of(parse_duration("10 parsecs")) ==
        "'10 parsecs' has an unknown unit 'parsecs'; use ns, us, ms or s");
  CHECK(error_of(parse_duration("10 mS")) ==
        "'10 mS' has an unknown unit 'mS'; did you mean 'ms'?");
  CHECK(error_of(parse_duration("5 min")) ==
        "'5 min' has an unknown unit 'min'; use ns, us, ms or s");
  CHECK(error_of(parse_duration("100Hz")) ==
        "'100Hz' is a rate; a duration is expected here (use ns, us, ms or s)");
}

TEST_CASE("Negative, overflowing and malformed durations are errors", "[config][units]") {
  CHECK(error_of(parse_duration("-5ms")) == "'-5ms' is negative; a duration must be zero or more");
  CHECK(parse_duration("-0ms") == 0);
  CHECK(error_of(parse_duration("300 years")).find("unknown unit 'years'") != std::string::npos);
  CHECK(error_of(parse_duration("1e30s")) == "'1e30s' is too long (the limit is about 292 years)");
  CHECK(error_of(parse_duration("9223372036.854775808s")) ==
        "'9223372036.854775808s' is too long (the limit is about 292 years)");
  CHECK(error_of(parse_duration("abc")) == "expected a duration such as '2.5ms', got 'abc'");
  CHECK(error_of(parse_duration("")) == "expected a duration such as '2.5ms'");
  CHECK(error_of(parse_duration("ms")) == "expected a duration such as '2.5ms', got 'ms'");
  CHECK(error_of(parse_duration("1.2.3ms")) ==
        "'1.2.3ms' has an unknown unit '.3ms'; use ns, us, ms or s");
  CHECK(error_of(parse_duration("12345678901234567891ns")).find("expected a duration") !=
        std::string::npos);  // more than 19 significant digits
}

TEST_CASE("A bare number is a duration only when the schema names its unit", "[config][units]") {
  CHECK(error_of(parse_duration("5")) == "'5' has no unit; use ns, us, ms or s (e.g. '5ms')");
  CHECK(parse_duration("5", TimeUnit::Millis) == 5 * kNanosPerMilli);
  CHECK(parse_duration("2.5", TimeUnit::Micros) == 2'500);
  CHECK(parse_duration("7", TimeUnit::Nanos) == 7);
  CHECK(parse_duration("2", TimeUnit::Seconds) == 2 * kNanosPerSecond);
  CHECK(parse_duration("5us", TimeUnit::Millis) == 5'000);  // an explicit unit wins
}

TEST_CASE("Rates parse to their period in nanoseconds", "[config][units]") {
  CHECK(parse_rate_as_period("1 kHz") == kNanosPerMilli);
  CHECK(parse_rate_as_period("100Hz") == 10 * kNanosPerMilli);
  CHECK(parse_rate_as_period("1MHz") == 1'000);
  CHECK(parse_rate_as_period("2.5 kHz") == 400'000);
  CHECK(parse_rate_as_period("0.1Hz") == 10 * kNanosPerSecond);
  CHECK(parse_rate_as_period("3Hz") == 333'333'333);     // rounded to nearest
  CHECK(parse_rate_as_period("1.5 Hz") == 666'666'667);  // rounded to nearest
  CHECK(parse_rate_as_period("1e-9 Hz") == kNanosPerSecond * 1'000'000'000);
}

TEST_CASE("Bad rates are errors", "[config][units]") {
  CHECK(error_of(parse_rate_as_period("0Hz")) == "'0Hz' is not a positive rate");
  CHECK(error_of(parse_rate_as_period("-5 kHz")) == "'-5 kHz' is not a positive rate");
  CHECK(error_of(parse_rate_as_period("1 khz")) ==
        "'1 khz' has an unknown unit 'khz'; did you mean 'kHz'?");
  CHECK(error_of(parse_rate_as_period("100")) ==
        "'100' has no unit; use Hz, kHz or MHz (e.g. '100Hz')");
  CHECK(error_of(parse_rate_as_period("1ms")) ==
        "'1ms' is a duration; a rate is expected here (use Hz, kHz or MHz)");
  CHECK(error_of(parse_rate_as_period("5000 MHz")) ==
        "'5000 MHz' is too high: its period is shorter than 1ns");
  CHECK(error_of(parse_rate_as_period("1e-12 Hz")) ==
        "'1e-12 Hz' is too low: its period is longer than about 292 years");
}

TEST_CASE("A period accepts a duration or a rate", "[config][units]") {
  CHECK(parse_period("1ms") == kNanosPerMilli);
  CHECK(parse_period("1 kHz") == kNanosPerMilli);
  CHECK(parse_period("4", TimeUnit::Millis) == 4 * kNanosPerMilli);
  CHECK(error_of(parse_period("10 parsecs")) ==
        "'10 parsecs' has an unknown unit 'parsecs'; use ns, us, ms, s, Hz, kHz or MHz");
  CHECK(error_of(parse_period("4")) ==
        "'4' has no unit; use ns, us, ms, s, Hz, kHz or MHz (e.g. '4ms')");
}

TEST_CASE("format_duration picks the largest unit and round-trips", "[config][units]") {
  CHECK(format_duration(0) == "0ns");
  CHECK(format_duration(999) == "999ns");
  CHECK(format_duration(1'000) == "1us");
  CHECK(format_duration(1'500'000) == "1.5ms");
  CHECK(format_duration(2 * kNanosPerSecond) == "2s");
  CHECK(format_duration(1'000'000'001) == "1.000000001s");
  CHECK(format_duration(-5'000) == "-5us");
  CHECK(format_duration(INT64_MIN) == "-9223372036.854775808s");
  for (const Nanos v : {Nanos{1}, Nanos{1'234}, Nanos{1'000'001}, Nanos{86'400} * kNanosPerSecond,
                        Nanos{INT64_MAX}}) {
    CHECK(parse_duration(format_duration(v)) == v);
  }
}
