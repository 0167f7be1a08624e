#include "vigil/export/json_writer.hpp"

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>

#include "support/json_reader.hpp"

using vigil::exporter::JsonWriter;
using vigil::test::JsonParser;

namespace {
std::string quoted(std::string_view s) {
  std::string out;
  vigil::exporter::append_json_string(out, s);
  return out;
}
}  // namespace

TEST_CASE("JSON strings are escaped per RFC 8259", "[export][json]") {
  CHECK(quoted("plain") == R"("plain")");
  CHECK(quoted("") == R"("")");
  CHECK(quoted("a\"b\\c") == R"("a\"b\\c")");
  CHECK(quoted("\b\f\n\r\t") == R"("\b\f\n\r\t")");
  CHECK(quoted(std::string_view("\x00\x01\x1f", 3)) == R"("\u0000\u0001\u001f")");
  CHECK(quoted("/ and \x7f stay") == "\"/ and \x7f stay\"");  // not required to be escaped
}

TEST_CASE("JSON strings keep valid UTF-8 and repair invalid bytes", "[export][json]") {
  CHECK(quoted("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80") ==
        "\"caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80\"");
  // A multi-byte character cut by a fixed-size name, a stray continuation byte, an overlong
  // encoding, a UTF-16 surrogate, a code point above U+10FFFF: one U+FFFD per bad byte.
  CHECK(quoted("ab\xe2\x82") == R"("ab\ufffd\ufffd")");
  CHECK(quoted("\x80x") == R"("\ufffdx")");
  CHECK(quoted("\xc0\xaf") == R"("\ufffd\ufffd")");
  CHECK(quoted("\xed\xa0\x80") == R"("\ufffd\ufffd\ufffd")");
  CHECK(quoted("\xf4\x90\x80\x80") == R"("\ufffd\ufffd\ufffd\ufffd")");
  // Line separators are valid JSON but break JavaScript: escaped.
  CHECK(quoted("a\xe2\x80\xa8"
               "b\xe2\x80\xa9") == R"("a\u2028b\u2029")");
  // Whatever the input, the output parses back.
  std::string all;
  for (int c = 0; c < 256; ++c) all += static_cast<char>(c);
  const auto j = JsonParser::parse(quoted(all));
  CHECK(j.is_string());
  CHECK(j.str().substr(0, 32).size() == 32);
}

TEST_CASE("JSON numbers: integers exactly, doubles shortest, NaN and infinities as null",
          "[export][json]") {
  JsonWriter w;
  w.begin_array();
  w.value(0).value(-42).value(std::numeric_limits<std::int64_t>::min());
  w.value(std::numeric_limits<std::uint64_t>::max());
  w.value(0.1).value(1.5e-9).value(1e21).value(-0.0).value(2.0);
  w.value(std::nan("")).value(std::numeric_limits<double>::infinity());
  w.end_array();
  CHECK(w.str() ==
        "[0,-42,-9223372036854775808,18446744073709551615,0.1,1.5e-09,1e+21,-0,2,null,null]");
  const auto j = JsonParser::parse(w.str());
  CHECK(j[4].number() == 0.1);
  CHECK(j[5].number() == 1.5e-9);
  CHECK(j[3].number_text() == "18446744073709551615");
}

TEST_CASE("JSON objects and arrays nest with commas in the right places", "[export][json]") {
  JsonWriter w;
  w.begin_object();
  w.field("schema", 1);
  w.field("name", "motor");
  w.field("ok", true);
  w.key("none").null();
  w.key("empty_object").begin_object().end_object();
  w.key("empty_array").begin_array().end_array();
  w.key("list").begin_array();
  w.begin_object().field("a", 1).end_object();
  w.begin_array().value("x").value(false).end_array();
  w.end_array();
  w.end_object();
  CHECK(w.complete());
  CHECK(w.str() == R"({"schema":1,"name":"motor","ok":true,"none":null,"empty_object":{},)"
                   R"("empty_array":[],"list":[{"a":1},["x",false]]})");
  const auto j = JsonParser::parse(w.str());
  CHECK(j["list"][1][0].str() == "x");
}

TEST_CASE("Indented JSON puts members on their own lines and parses the same", "[export][json]") {
  JsonWriter w(2);
  w.begin_object().field("a", 1).key("b").begin_array().value(2).value(3).end_array();
  w.key("c").begin_object().end_object().end_object();
  CHECK(w.str() == "{\n  \"a\": 1,\n  \"b\": [\n    2,\n    3\n  ],\n  \"c\": {}\n}");
  CHECK(JsonParser::parse(w.str())["b"][1].number() == 3);
}

TEST_CASE("take() returns the text and resets the writer", "[export][json]") {
  JsonWriter w;
  w.value("x");
  CHECK(w.complete());
  CHECK(w.take() == R"("x")");
  CHECK_FALSE(w.complete());
  w.begin_array().end_array();
  CHECK(w.str() == "[]");
}
