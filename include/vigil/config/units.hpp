#pragma once
/// @file
/// Durations and rates written with units: `"1ms"`, `"500us"`, `"2.5 s"`, `"10ns"`, `"1 kHz"`,
/// `"100Hz"`.
///
/// Syntax: an optional '+', a decimal number (`5`, `2.5`, `.5`, `1e-3`), optional spaces or tabs,
/// then a unit. Duration units: `ns`, `us` (also `µs`, `μs`), `ms`, `s`. Rate units: `Hz`, `kHz`,
/// `MHz`. Units are case-sensitive (`mHz` and `MHz` differ by a factor of 10⁹); a near miss gets
/// a "did you mean" hint. Durations are exact: `2.5ms` is 2'500'000 ns, and a value that is not a
/// whole number of nanoseconds (`1.5ns`) is an error, never rounded. A rate is returned as its
/// period in nanoseconds, rounded to the nearest nanosecond (`3Hz` is 333'333'333 ns). Negative
/// values, a zero rate and values that do not fit in `vigil::Nanos` are errors.
///
/// None of these functions is RT-safe (they allocate their error messages); all are thread-safe.

#include <cstdint>
#include <string>
#include <string_view>

#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::config {

/// The unit of a bare number (`5`) written where a duration is expected.
///
/// `None` (the default everywhere) rejects bare numbers: "'5' has no unit". A schema that wants
/// bare numbers must name their unit, and should say it in the key (`timeout_ms: 5`).
enum class TimeUnit : std::uint8_t {
  None,     ///< A bare number is an error.
  Nanos,    ///< A bare number counts nanoseconds.
  Micros,   ///< A bare number counts microseconds.
  Millis,   ///< A bare number counts milliseconds.
  Seconds,  ///< A bare number counts seconds.
};

/// Parses a duration (`"2.5 ms"`) into nanoseconds, exactly.
///
/// Fails with a message that quotes `text` and says what is wrong: no number, no unit (unless
/// `bare_unit` names one), an unknown unit (with a hint), a negative value, a fraction of a
/// nanosecond, or an overflow (more than about 292 years). Not RT-safe (allocates on error).
[[nodiscard]] expected<Nanos, std::string> parse_duration(std::string_view text,
                                                          TimeUnit bare_unit = TimeUnit::None);

/// Parses a rate (`"1 kHz"`, `"100Hz"`) and returns its period in nanoseconds, rounded to the
/// nearest nanosecond.
///
/// Fails on a missing or unknown unit (only Hz, kHz, MHz), a rate that is zero or negative, a
/// rate so high that the period is below 0.5 ns, or one so low that the period overflows.
/// Not RT-safe (allocates on error).
[[nodiscard]] expected<Nanos, std::string> parse_rate_as_period(std::string_view text);

/// Parses a period written either as a duration (`"1ms"`) or as a rate (`"1 kHz"`), in
/// nanoseconds; the unit decides. Bare numbers follow `bare_unit` as in `parse_duration`.
/// Fails as `parse_duration` and `parse_rate_as_period` do. Not RT-safe (allocates on error).
[[nodiscard]] expected<Nanos, std::string> parse_period(std::string_view text,
                                                        TimeUnit bare_unit = TimeUnit::None);

/// Formats nanoseconds with the largest unit that keeps the value at least 1 and without
/// losing digits: `1'500'000` → `"1.5ms"`, `999` → `"999ns"`, `2'000'000'000` → `"2s"`,
/// `0` → `"0ns"`, `-5'000` → `"-5us"`. A non-negative result parses back to the same value.
/// Not RT-safe (allocates).
[[nodiscard]] std::string format_duration(Nanos ns);

}  // namespace vigil::config
