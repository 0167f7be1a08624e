#pragma once
/// @file
/// `FixedString<N>`: a string of at most N-1 characters stored inline, trivially copyable, so
/// that messages carrying names and texts never allocate.

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <string>
#include <string_view>

namespace vigil::bus {

/// Inline, NUL-terminated, fixed-capacity string. Longer input is truncated (never an error:
/// names and exception texts are informative, and truncation must not cost the RT side).
/// All members are RT-safe (no allocation, no exception) except `str()`.
template <std::size_t N>
struct FixedString {
  static_assert(N >= 2 && N <= 256, "FixedString capacity must be 2..256");
  char data_[N] = {};

  constexpr FixedString() noexcept = default;
  // Implicit by design: a message field is assigned from a string like a std::string.
  FixedString(std::string_view s) noexcept { assign(s); }  // NOLINT(google-explicit-constructor)
  FixedString(const char* s) noexcept {                    // NOLINT(google-explicit-constructor)
    assign(s ? std::string_view(s) : std::string_view());
  }

  /// Copies at most N-1 characters of `s`. RT-safe.
  void assign(std::string_view s) noexcept {
    const std::size_t n = std::min(s.size(), N - 1);
    if (n > 0) std::memcpy(data_, s.data(), n);
    data_[n] = '\0';
  }
  [[nodiscard]] std::string_view view() const noexcept {
    return std::string_view(data_, ::strnlen(data_, N));
  }
  [[nodiscard]] const char* c_str() const noexcept { return data_; }
  [[nodiscard]] std::size_t size() const noexcept { return ::strnlen(data_, N); }
  [[nodiscard]] bool empty() const noexcept { return data_[0] == '\0'; }
  [[nodiscard]] static constexpr std::size_t capacity() noexcept { return N - 1; }
  /// Allocates: not RT-safe.
  [[nodiscard]] std::string str() const { return std::string(view()); }

  friend bool operator==(const FixedString& a, const FixedString& b) noexcept {
    return a.view() == b.view();
  }
  friend bool operator==(const FixedString& a, std::string_view b) noexcept {
    return a.view() == b;
  }
};

}  // namespace vigil::bus

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using bus::FixedString;
}  // namespace vigil
