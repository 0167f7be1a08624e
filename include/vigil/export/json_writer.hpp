#pragma once
/// @file
/// `JsonWriter`: a small streaming JSON writer (RFC 8259) for vigil's exporters: objects, arrays,
/// strings, numbers, booleans and null, compact or indented.
///
/// Strings are escaped per RFC 8259 §7: `"` and `\` and every control character below U+0020
/// (as \b \f \n \r \t, or \u00XX); U+2028 and U+2029 are escaped too, so that the output can be
/// embedded in JavaScript. Input that is not valid UTF-8 (a name truncated in the middle of a
/// character by a fixed-size message, a binary exception text) is repaired: each invalid byte
/// becomes U+FFFD, so the output is always valid JSON. Numbers: integers exactly; finite doubles
/// in the shortest form that reads back to the same value; NaN and infinities, which JSON
/// cannot represent, as null.
///
/// Misuse (a value where a key is expected, closing what is not open) is a contract violation
/// checked with VIGIL_ASSERT in debug builds. Not thread-safe (a plain object); not RT-safe
/// (allocates).
///
/// **Example**:
/// ```
/// vigil::JsonWriter w;
/// w.begin_object().field("schema", 1).key("names").begin_array().value("a").end_array();
/// w.end_object();
/// // w.str() == R"({"schema":1,"names":["a"]})"
/// ```

#include <concepts>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace vigil::exporter {

/// Appends `s` to `out` as a JSON string literal (with the quotes), escaped and UTF-8-repaired
/// as described in the file comment.
void append_json_string(std::string& out, std::string_view s);

/// Appends `v` as a JSON number (null for NaN and infinities).
void append_json_number(std::string& out, double v);

class JsonWriter {
 public:
  /// `indent` = 0 writes compact JSON; > 0 puts each member and element on its own line,
  /// indented by that many spaces per level.
  explicit JsonWriter(int indent = 0);

  JsonWriter& begin_object();
  JsonWriter& end_object();
  JsonWriter& begin_array();
  JsonWriter& end_array();
  /// The key of the next member (inside an object only).
  JsonWriter& key(std::string_view k);

  JsonWriter& value(std::string_view s);
  JsonWriter& value(const std::string& s) { return value(std::string_view(s)); }
  JsonWriter& value(const char* s) { return value(std::string_view(s)); }
  JsonWriter& value(bool b);
  JsonWriter& value(double v);
  template <std::integral T>
  requires(!std::same_as<T, bool> && !std::same_as<T, char>) JsonWriter& value(T v) {
    if constexpr (std::is_signed_v<T>) {
      return integer_(static_cast<std::int64_t>(v));
    } else {
      return unsigned_(static_cast<std::uint64_t>(v));
    }
  }
  JsonWriter& null();

  /// `key(k).value(v)`.
  template <class T>
  JsonWriter& field(std::string_view k, const T& v) {
    key(k);
    return value(v);
  }

  /// The text written so far.
  [[nodiscard]] const std::string& str() const noexcept { return out_; }
  /// Moves the text out and resets the writer.
  [[nodiscard]] std::string take();
  /// True when exactly one complete value has been written (every object and array closed).
  [[nodiscard]] bool complete() const noexcept { return stack_.empty() && wrote_root_; }

 private:
  enum class Frame : std::uint8_t { Object, Array };
  void before_value_();
  void newline_();
  JsonWriter& integer_(std::int64_t v);
  JsonWriter& unsigned_(std::uint64_t v);

  std::string out_;
  std::vector<Frame> stack_;
  std::vector<bool> first_;  // per open container: nothing written in it yet
  int indent_;
  bool after_key_ = false;
  bool wrote_root_ = false;
};

}  // namespace vigil::exporter
