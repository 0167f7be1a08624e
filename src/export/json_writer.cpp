#include "vigil/export/json_writer.hpp"

#include <charconv>
#include <cmath>

#include "utf8.hpp"
#include "vigil/assert.hpp"

namespace vigil::exporter {

namespace {

constexpr char kHex[] = "0123456789abcdef";

void append_u_escape(std::string& out, unsigned code) {
  out += "\\u";
  out += kHex[(code >> 12) & 0xF];
  out += kHex[(code >> 8) & 0xF];
  out += kHex[(code >> 4) & 0xF];
  out += kHex[code & 0xF];
}

}  // namespace

void append_json_string(std::string& out, std::string_view s) {
  out += '"';
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      switch (c) {
        case '"':
          out += "\\\"";
          break;
        case '\\':
          out += "\\\\";
          break;
        case '\b':
          out += "\\b";
          break;
        case '\f':
          out += "\\f";
          break;
        case '\n':
          out += "\\n";
          break;
        case '\r':
          out += "\\r";
          break;
        case '\t':
          out += "\\t";
          break;
        default:
          if (c < 0x20) {
            append_u_escape(out, c);
          } else {
            out += static_cast<char>(c);
          }
      }
      ++i;
      continue;
    }
    unsigned code = 0;
    const std::size_t n = exporter::detail::utf8_sequence(s, i, code);
    if (n == 0) {
      out += "\\ufffd";  // one replacement character per invalid byte
      ++i;
    } else if (code == 0x2028 || code == 0x2029) {
      append_u_escape(out, code);  // valid JSON, but line terminators in JavaScript
      i += n;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
  out += '"';
}

void append_json_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form
  out.append(buf, r.ptr);
}

JsonWriter::JsonWriter(int indent) : indent_(indent < 0 ? 0 : indent) {}

void JsonWriter::newline_() {
  if (indent_ == 0) return;
  out_ += '\n';
  out_.append(stack_.size() * static_cast<std::size_t>(indent_), ' ');
}

void JsonWriter::before_value_() {
  if (stack_.empty()) {
    VIGIL_ASSERT(!wrote_root_, "JsonWriter: a document holds one root value");
    wrote_root_ = true;
    return;
  }
  if (stack_.back() == Frame::Object) {
    VIGIL_ASSERT(after_key_, "JsonWriter: a value inside an object needs a key first");
    after_key_ = false;
    return;
  }
  if (!first_.back()) out_ += ',';
  first_.back() = false;
  newline_();
}

JsonWriter& JsonWriter::begin_object() {
  before_value_();
  out_ += '{';
  stack_.push_back(Frame::Object);
  first_.push_back(true);
  return *this;
}

JsonWriter& JsonWriter::end_object() {
  VIGIL_ASSERT(!stack_.empty() && stack_.back() == Frame::Object && !after_key_,
               "JsonWriter: end_object without a matching begin_object (or after a key)");
  const bool empty = first_.back();
  stack_.pop_back();
  first_.pop_back();
  if (!empty) newline_();
  out_ += '}';
  return *this;
}

JsonWriter& JsonWriter::begin_array() {
  before_value_();
  out_ += '[';
  stack_.push_back(Frame::Array);
  first_.push_back(true);
  return *this;
}

JsonWriter& JsonWriter::end_array() {
  VIGIL_ASSERT(!stack_.empty() && stack_.back() == Frame::Array,
               "JsonWriter: end_array without a matching begin_array");
  const bool empty = first_.back();
  stack_.pop_back();
  first_.pop_back();
  if (!empty) newline_();
  out_ += ']';
  return *this;
}

JsonWriter& JsonWriter::key(std::string_view k) {
  VIGIL_ASSERT(!stack_.empty() && stack_.back() == Frame::Object && !after_key_,
               "JsonWriter: key outside an object, or two keys in a row");
  if (!first_.back()) out_ += ',';
  first_.back() = false;
  newline_();
  append_json_string(out_, k);
  out_ += indent_ > 0 ? ": " : ":";
  after_key_ = true;
  return *this;
}

JsonWriter& JsonWriter::value(std::string_view s) {
  before_value_();
  append_json_string(out_, s);
  return *this;
}

JsonWriter& JsonWriter::value(bool b) {
  before_value_();
  out_ += b ? "true" : "false";
  return *this;
}

JsonWriter& JsonWriter::value(double v) {
  before_value_();
  append_json_number(out_, v);
  return *this;
}

JsonWriter& JsonWriter::null() {
  before_value_();
  out_ += "null";
  return *this;
}

JsonWriter& JsonWriter::integer_(std::int64_t v) {
  before_value_();
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out_.append(buf, r.ptr);
  return *this;
}

JsonWriter& JsonWriter::unsigned_(std::uint64_t v) {
  before_value_();
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out_.append(buf, r.ptr);
  return *this;
}

std::string JsonWriter::take() {
  std::string s = std::move(out_);
  out_.clear();
  stack_.clear();
  first_.clear();
  after_key_ = false;
  wrote_root_ = false;
  return s;
}

}  // namespace vigil::exporter
