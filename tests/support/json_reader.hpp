#pragma once
// A small, strict JSON reader (RFC 8259) for tests that check what vigil's exporters write.
// Test-only: it throws std::runtime_error with the offset on any deviation from the grammar, so
// parsing an exporter's output also proves that the output is valid JSON.

#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace vigil::test {

struct Json {
  using Array = std::vector<Json>;
  using Object = std::map<std::string, Json>;  // duplicate keys are rejected by the parser
  struct Number {
    double value = 0;
    std::string text;  // as written, to check integers exactly
  };
  std::variant<std::nullptr_t, bool, Number, std::string, Array, Object> v;

  [[nodiscard]] bool is_null() const { return std::holds_alternative<std::nullptr_t>(v); }
  [[nodiscard]] bool is_bool() const { return std::holds_alternative<bool>(v); }
  [[nodiscard]] bool is_number() const { return std::holds_alternative<Number>(v); }
  [[nodiscard]] bool is_string() const { return std::holds_alternative<std::string>(v); }
  [[nodiscard]] bool is_array() const { return std::holds_alternative<Array>(v); }
  [[nodiscard]] bool is_object() const { return std::holds_alternative<Object>(v); }
  /// True for a number written without fraction or exponent.
  [[nodiscard]] bool is_integer() const {
    return is_number() && std::get<Number>(v).text.find_first_of(".eE") == std::string::npos;
  }

  [[nodiscard]] bool boolean() const { return std::get<bool>(v); }
  [[nodiscard]] double number() const { return std::get<Number>(v).value; }
  [[nodiscard]] const std::string& number_text() const { return std::get<Number>(v).text; }
  [[nodiscard]] const std::string& str() const { return std::get<std::string>(v); }
  [[nodiscard]] const Array& array() const { return std::get<Array>(v); }
  [[nodiscard]] const Object& object() const { return std::get<Object>(v); }
  [[nodiscard]] bool has(const std::string& key) const {
    return is_object() && object().count(key) != 0;
  }
  [[nodiscard]] const Json& operator[](const std::string& key) const {
    const auto& o = object();
    const auto it = o.find(key);
    if (it == o.end()) throw std::out_of_range("no key '" + key + "'");
    return it->second;
  }
  [[nodiscard]] const Json& operator[](std::size_t i) const { return array().at(i); }
};

class JsonParser {
 public:
  static Json parse(std::string_view text) {
    JsonParser p(text);
    p.ws();
    Json j = p.value(0);
    p.ws();
    if (p.i_ != text.size()) p.fail("trailing characters");
    return j;
  }

 private:
  explicit JsonParser(std::string_view t) : t_(t) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error("JSON: " + what + " at offset " + std::to_string(i_));
  }
  [[nodiscard]] bool end() const { return i_ >= t_.size(); }
  [[nodiscard]] char peek() const { return end() ? '\0' : t_[i_]; }
  void expect(char c) {
    if (peek() != c) fail(std::string("expected '") + c + "'");
    ++i_;
  }
  void ws() {
    while (!end() && (t_[i_] == ' ' || t_[i_] == '\t' || t_[i_] == '\n' || t_[i_] == '\r')) ++i_;
  }
  void literal(std::string_view word) {
    if (t_.substr(i_, word.size()) != word) fail("bad literal");
    i_ += word.size();
  }

  Json value(int depth) {
    if (depth > 64) fail("too deep");
    switch (peek()) {
      case '{':
        return object(depth);
      case '[':
        return array(depth);
      case '"':
        return Json{string()};
      case 't':
        literal("true");
        return Json{true};
      case 'f':
        literal("false");
        return Json{false};
      case 'n':
        literal("null");
        return Json{nullptr};
      default:
        return number();
    }
  }

  Json object(int depth) {
    expect('{');
    Json::Object o;
    ws();
    if (peek() == '}') {
      ++i_;
      return Json{std::move(o)};
    }
    while (true) {
      ws();
      std::string k = string();
      ws();
      expect(':');
      ws();
      if (o.count(k) != 0) fail("duplicate key '" + k + "'");
      o.emplace(std::move(k), value(depth + 1));
      ws();
      if (peek() == ',') {
        ++i_;
        continue;
      }
      expect('}');
      return Json{std::move(o)};
    }
  }

  Json array(int depth) {
    expect('[');
    Json::Array a;
    ws();
    if (peek() == ']') {
      ++i_;
      return Json{std::move(a)};
    }
    while (true) {
      ws();
      a.push_back(value(depth + 1));
      ws();
      if (peek() == ',') {
        ++i_;
        continue;
      }
      expect(']');
      return Json{std::move(a)};
    }
  }

  unsigned hex4() {
    if (i_ + 4 > t_.size()) fail("short \\u escape");
    unsigned v = 0;
    for (int k = 0; k < 4; ++k) {
      const char c = t_[i_++];
      v <<= 4;
      if (c >= '0' && c <= '9') {
        v |= static_cast<unsigned>(c - '0');
      } else if (c >= 'a' && c <= 'f') {
        v |= static_cast<unsigned>(c - 'a' + 10);
      } else if (c >= 'A' && c <= 'F') {
        v |= static_cast<unsigned>(c - 'A' + 10);
      } else {
        fail("bad hex digit");
      }
    }
    return v;
  }

  static void utf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out += static_cast<char>(cp);
    } else if (cp < 0x800) {
      out += static_cast<char>(0xC0 | (cp >> 6));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      out += static_cast<char>(0xE0 | (cp >> 12));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (cp >> 18));
      out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    }
  }

  std::string string() {
    expect('"');
    std::string out;
    while (true) {
      if (end()) fail("unterminated string");
      const auto c = static_cast<unsigned char>(t_[i_++]);
      if (c == '"') return out;
      if (c < 0x20) fail("unescaped control character");
      if (c != '\\') {
        out += static_cast<char>(c);
        continue;
      }
      if (end()) fail("bad escape");
      const char e = t_[i_++];
      switch (e) {
        case '"':
        case '\\':
        case '/':
          out += e;
          break;
        case 'b':
          out += '\b';
          break;
        case 'f':
          out += '\f';
          break;
        case 'n':
          out += '\n';
          break;
        case 'r':
          out += '\r';
          break;
        case 't':
          out += '\t';
          break;
        case 'u': {
          unsigned cp = hex4();
          if (cp >= 0xD800 && cp <= 0xDBFF) {
            expect('\\');
            expect('u');
            const unsigned lo = hex4();
            if (lo < 0xDC00 || lo > 0xDFFF) fail("bad surrogate pair");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          } else if (cp >= 0xDC00 && cp <= 0xDFFF) {
            fail("lone low surrogate");
          }
          utf8(out, cp);
          break;
        }
        default:
          fail("bad escape");
      }
    }
  }

  Json number() {
    const std::size_t start = i_;
    if (peek() == '-') ++i_;
    if (peek() == '0') {
      ++i_;
    } else if (peek() >= '1' && peek() <= '9') {
      while (peek() >= '0' && peek() <= '9') ++i_;
    } else {
      fail("bad value");
    }
    if (peek() == '.') {
      ++i_;
      if (!(peek() >= '0' && peek() <= '9')) fail("bad fraction");
      while (peek() >= '0' && peek() <= '9') ++i_;
    }
    if (peek() == 'e' || peek() == 'E') {
      ++i_;
      if (peek() == '+' || peek() == '-') ++i_;
      if (!(peek() >= '0' && peek() <= '9')) fail("bad exponent");
      while (peek() >= '0' && peek() <= '9') ++i_;
    }
    std::string text(t_.substr(start, i_ - start));
    const double v = std::strtod(text.c_str(), nullptr);
    return Json{Json::Number{v, std::move(text)}};
  }

  std::string_view t_;
  std::size_t i_ = 0;
};

}  // namespace vigil::test
