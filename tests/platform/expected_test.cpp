#include "vigil/expected.hpp"

#include <catch2/catch.hpp>
#include <string>

#include "vigil/error.hpp"

namespace {
vigil::expected<int, vigil::Error> parse_positive(int v) {
  if (v <= 0) return vigil::unexpected(vigil::Error{EINVAL, "not positive"});
  return v;
}
}  // namespace

TEST_CASE("vigil::expected carries a value or an Error", "[platform][expected]") {
  const auto ok = parse_positive(3);
  REQUIRE(ok.has_value());
  CHECK(*ok == 3);
  const auto bad = parse_positive(-1);
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().code == EINVAL);
  CHECK(bad.error().message == "not positive");
  CHECK(bad.value_or(7) == 7);
}
