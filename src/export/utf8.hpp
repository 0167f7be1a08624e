#pragma once
/// UTF-8 validation shared by the export module's writers (JSON strings, Prometheus labels).
/// Private to src/export/.

#include <cstddef>
#include <string_view>

namespace vigil::exporter::detail {

/// Length of the valid UTF-8 sequence starting at `s[i]` (1 for ASCII), or 0 when it is invalid:
/// overlong forms, surrogates, code points above U+10FFFF and truncated sequences are all invalid
/// (RFC 3629). `code` receives the code point of a valid sequence. Requires `i < s.size()`.
inline std::size_t utf8_sequence(std::string_view s, std::size_t i, unsigned& code) noexcept {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned c0 = b(0);
  if (c0 < 0x80) {
    code = c0;
    return 1;
  }
  std::size_t n = 0;
  unsigned min = 0;
  if (c0 >= 0xC2 && c0 <= 0xDF) {
    n = 2;
    code = c0 & 0x1F;
    min = 0x80;
  } else if (c0 >= 0xE0 && c0 <= 0xEF) {
    n = 3;
    code = c0 & 0x0F;
    min = 0x800;
  } else if (c0 >= 0xF0 && c0 <= 0xF4) {
    n = 4;
    code = c0 & 0x07;
    min = 0x10000;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xC0) != 0x80) return 0;
    code = (code << 6) | (b(k) & 0x3F);
  }
  if (code < min || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return n;
}

}  // namespace vigil::exporter::detail
