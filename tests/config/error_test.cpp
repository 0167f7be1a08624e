#include "vigil/config/error.hpp"

#include <catch2/catch.hpp>
#include <sstream>

using vigil::config::closest_match;
using vigil::config::ConfigError;
using vigil::config::ConfigErrors;

TEST_CASE("ConfigError formats as file:line:col: field: message", "[config][error]") {
  const ConfigError e{"monitor.yaml", 3, 11, "monitor.period", "expected a duration"};
  CHECK(e.to_string() == "monitor.yaml:3:11: monitor.period: expected a duration");
  std::ostringstream out;
  out << e;
  CHECK(out.str() == e.to_string());
}

TEST_CASE("ConfigError leaves out unknown line, column and empty field", "[config][error]") {
  CHECK(
      ConfigError{"a.yaml", 0, 0, "", "cannot read file: No such file or directory"}.to_string() ==
      "a.yaml: cannot read file: No such file or directory");
  CHECK(ConfigError{"a.yaml", 4, 0, "x", "bad"}.to_string() == "a.yaml:4: x: bad");
  CHECK(ConfigError{"a.yaml", 4, 2, "", "illegal map value"}.to_string() ==
        "a.yaml:4:2: illegal map value");
}

TEST_CASE("A list of errors prints one per line", "[config][error]") {
  const ConfigErrors errors{{"a.yaml", 1, 1, "x", "one"}, {"a.yaml", 2, 3, "y", "two"}};
  CHECK(vigil::config::to_string(errors) == "a.yaml:1:1: x: one\na.yaml:2:3: y: two");
  CHECK(vigil::config::to_string(ConfigErrors{}).empty());
}

TEST_CASE("closest_match suggests near misses and nothing for unrelated words", "[config][error]") {
  CHECK(closest_match("warn_fractoin", {"period", "warn_fraction", "error_fraction"}) ==
        "warn_fraction");
  CHECK(closest_match("FIFOO", {"FIFO", "OTHER"}) == "FIFO");
  CHECK(closest_match("fifo", {"FIFO", "OTHER"}) == "FIFO");  // letter case only
  CHECK(closest_match("mS", {"ns", "us", "ms", "s"}) == "ms");
  CHECK(closest_match("perod", {"period", "priority"}) == "period");
  CHECK_FALSE(closest_match("parsecs", {"ns", "us", "ms", "s"}).has_value());
  CHECK_FALSE(closest_match("x", {"a", "b"}).has_value());
  CHECK_FALSE(closest_match("anything", {}).has_value());
}
