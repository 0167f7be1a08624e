#include "vigil/bus/fixed_string.hpp"

#include <catch2/catch.hpp>
#include <string>

using vigil::FixedString;

TEST_CASE("FixedString stores short strings and truncates long ones", "[bus][fixed_string]") {
  FixedString<8> s("motor");
  CHECK(s.view() == "motor");
  CHECK(s.size() == 5);
  s.assign("a-very-long-name");
  CHECK(s.view() == "a-very-");
  CHECK(s.size() == FixedString<8>::capacity());
  FixedString<8> e;
  CHECK(e.empty());
  CHECK(e.view().empty());
  const FixedString<8> n(static_cast<const char*>(nullptr));
  CHECK(n.empty());
  CHECK(FixedString<8>("ab") == FixedString<8>("ab"));
  CHECK(FixedString<8>("ab") == std::string_view("ab"));
  CHECK(FixedString<8>("ab").str() == std::string("ab"));
}
