#include "vigil/config/node.hpp"

#include <array>
#include <catch2/catch.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "vigil/config/load.hpp"

using namespace vigil::config;
using vigil::kNanosPerMicro;
using vigil::kNanosPerMilli;
using vigil::Nanos;

namespace {

Node load(std::string_view text) {
  auto r = load_string(text, "t.yaml");
  REQUIRE(r.has_value());
  return *r;
}

// The only error recorded in `n`'s document.
ConfigError only_error(const Node& n) {
  const ConfigErrors errors = n.errors();
  INFO(to_string(errors));
  REQUIRE(errors.size() == 1);
  return errors.front();
}

ConfigError at(int line, int column, std::string field, std::string message) {
  return ConfigError{"t.yaml", line, column, std::move(field), std::move(message)};
}

enum class Policy { Fifo, Other };
constexpr std::array<EnumName<Policy>, 2> kPolicies{
    {{"FIFO", Policy::Fifo}, {"OTHER", Policy::Other}}};

}  // namespace

TEST_CASE("Values of every supported type are read", "[config][node]") {
  const Node n = load(
      "flag: true\n"
      "off: False\n"
      "count: -42\n"
      "id: 0x1F\n"
      "small: 255\n"
      "big: 9223372036854775807\n"
      "ratio: 0.25\n"
      "exp: +1.5e3\n"
      "f: 2.5\n"
      "name: motor\n"
      "quoted: \"12\"\n"
      "ids: [1, 2, 3]\n"
      "names: [a, b]\n");
  CHECK(n.required<bool>("flag"));
  CHECK_FALSE(n.required<bool>("off"));
  CHECK(n.required<int>("count") == -42);
  CHECK(n.required<std::uint32_t>("id") == 31);
  CHECK(n.required<std::uint8_t>("small") == 255);
  CHECK(n.required<std::int64_t>("big") == INT64_MAX);
  CHECK(n.required<double>("ratio") == 0.25);
  CHECK(n.required<double>("exp") == 1500.0);
  CHECK(n.required<float>("f") == 2.5f);
  CHECK(n.required<double>("count") == -42.0);
  CHECK(n.required<std::string>("name") == "motor");
  CHECK(n.required<std::string>("count") == "-42");  // any scalar is a string
  CHECK(n.required<int>("quoted") == 12);
  CHECK(n.required<std::vector<int>>("ids") == std::vector<int>{1, 2, 3});
  CHECK(n.required<std::vector<std::string>>("names") == std::vector<std::string>{"a", "b"});
  CHECK_FALSE(n.has_errors());
}

TEST_CASE("A type error names the field, line and column of the value", "[config][node]") {
  const Node n = load(
      "monitor:\n"
      "  warn_fraction: abc\n");
  CHECK(n["monitor"].required<double>("warn_fraction") == 0.0);
  CHECK(only_error(n) == at(2, 18, "monitor.warn_fraction", "expected a number, got 'abc'"));
  CHECK(only_error(n).to_string() ==
        "t.yaml:2:18: monitor.warn_fraction: expected a number, got 'abc'");
}

TEST_CASE("Type errors describe what was found", "[config][node]") {
  const Node n = load(
      "a: [1, 2]\n"                  // 1
      "b: {x: 1}\n"                  // 2
      "c: 5.0\n"                     // 3
      "d: 300\n"                     // 4
      "e: -1\n"                      // 5
      "f: yes\n"                     // 6
      "g: inf\n"                     // 7
      "h: 1e39\n"                    // 8
      "i: 99999999999999999999\n");  // 9
  (void)n.required<int>("a");
  (void)n.required<std::string>("b");
  (void)n.required<int>("c");
  (void)n.required<std::uint8_t>("d");
  (void)n.required<unsigned>("e");
  (void)n.required<bool>("f");
  (void)n.required<double>("g");
  (void)n.required<float>("h");
  (void)n.required<std::int64_t>("i");
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 9);
  CHECK(errors[0] == at(1, 4, "a", "expected an integer, got a sequence"));
  CHECK(errors[1] == at(2, 4, "b", "expected a string, got a mapping"));
  CHECK(errors[2] == at(3, 4, "c", "expected an integer, got '5.0'"));
  CHECK(errors[3] == at(4, 4, "d", "expected an integer between 0 and 255, got '300'"));
  CHECK(errors[4] == at(5, 4, "e", "expected an integer between 0 and 4294967295, got '-1'"));
  CHECK(errors[5] == at(6, 4, "f", "expected true or false, got 'yes'"));
  CHECK(errors[6] == at(7, 4, "g", "expected a finite number, got 'inf'"));
  CHECK(errors[7] == at(8, 4, "h", "expected a finite number within float range, got '1e39'"));
  CHECK(errors[8] ==
        at(9, 4, "i",
           "expected an integer between -9223372036854775808 and 9223372036854775807, got "
           "'99999999999999999999'"));
}

TEST_CASE("A missing required key is reported at the enclosing mapping", "[config][node]") {
  const Node n = load(
      "# comment\n"
      "monitor:\n"
      "  warn: 1\n");
  CHECK(n["monitor"].required<int>("period") == 0);
  CHECK(only_error(n) == at(3, 3, "monitor.period", "required key is missing"));
}

TEST_CASE("An empty value is an error, not a default", "[config][node]") {
  const Node n = load(
      "a:\n"
      "b: ~\n"
      "c: 1\n");
  CHECK(n.optional("a", 7) == 0);
  CHECK(n.optional<std::string>("b", "x").empty());
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 2);
  // yaml-cpp marks an empty value at the next token: the error points at the key instead.
  CHECK(errors[0] == at(1, 1, "a", "expected an integer, got an empty value"));
  CHECK(errors[1] == at(2, 4, "b", "expected a string, got an empty value"));
  CHECK(n["a"].is_null());
}

TEST_CASE("optional returns the fallback only when the key is absent", "[config][node]") {
  const Node n = load("present: 3\n");
  CHECK(n.optional("absent", 7) == 7);
  CHECK(n.optional("present", 7) == 3);
  CHECK(n.optional<std::string>("name", "motor") == "motor");
  CHECK(n["section"].optional("deep", 1.5) == 1.5);  // a whole optional section is absent
  CHECK_FALSE(n.has_errors());
}

TEST_CASE("Checks report the requirement and the value as written", "[config][node]") {
  const Node n = load(
      "ratio: 1.5\n"
      "priority: 0\n"
      "offset: -3\n"
      "name: ''\n"
      "period: 5s\n"
      "even: 3\n"
      "ok: 0.5\n");
  CHECK(n.required<double>("ratio", in_range(0.0, 1.0)) == 1.5);  // value kept, error recorded
  (void)n.required<int>("priority", positive());
  (void)n.required<int>("offset", non_negative());
  (void)n.required<std::string>("name", non_empty());
  (void)n.required_duration("period", duration_in_range(kNanosPerMilli, 1'000 * kNanosPerMilli));
  const auto even = [](int v) -> std::optional<std::string> {
    if (v % 2 == 0) return std::nullopt;
    return "must be even";
  };
  (void)n.required<int>("even", even);
  CHECK(n.required<double>("ok", in_range(0, 1), positive()) == 0.5);
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 6);
  CHECK(errors[0] == at(1, 8, "ratio", "must be between 0 and 1, got '1.5'"));
  CHECK(errors[1] == at(2, 11, "priority", "must be positive, got '0'"));
  CHECK(errors[2] == at(3, 9, "offset", "must be zero or more, got '-3'"));
  CHECK(errors[3] == at(4, 7, "name", "must not be empty, got ''"));
  CHECK(errors[4] == at(5, 9, "period", "must be between 1ms and 1s, got '5s'"));
  CHECK(errors[5] == at(6, 7, "even", "must be even, got '3'"));
}

TEST_CASE("Enumerations match names exactly and suggest the closest", "[config][node]") {
  const Node n = load(
      "a: OTHER\n"
      "policy: FIFOO\n"
      "c: [x]\n"
      "d: round_robin\n");
  CHECK(n.required_enum("a", kPolicies) == Policy::Other);
  CHECK(n.required_enum<Policy>("a", {{"FIFO", Policy::Fifo}, {"OTHER", Policy::Other}}) ==
        Policy::Other);
  CHECK(n.optional_enum("absent", Policy::Other, kPolicies) == Policy::Other);
  CHECK(n.optional_enum("absent", Policy::Fifo, {{"FIFO", Policy::Fifo}}) == Policy::Fifo);
  CHECK(n["a"].get_enum(kPolicies) == Policy::Other);
  (void)n.required_enum("policy", kPolicies);
  (void)n.required_enum("c", kPolicies);
  (void)n.required_enum("d", kPolicies);
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 3);
  CHECK(errors[0] == at(2, 9, "policy", "'FIFOO' is not one of FIFO, OTHER; did you mean 'FIFO'?"));
  CHECK(errors[0].to_string() ==
        "t.yaml:2:9: policy: 'FIFOO' is not one of FIFO, OTHER; did you mean 'FIFO'?");
  CHECK(errors[1] == at(3, 4, "c", "expected one of FIFO or OTHER, got a sequence"));
  CHECK(errors[2] == at(4, 4, "d", "'round_robin' is not one of FIFO, OTHER"));
}

TEST_CASE("Unknown keys are reported each at its own location with a suggestion",
          "[config][node]") {
  const Node n = load(
      "overrun:\n"
      "  warn_fractoin: 0.5\n"
      "  error_fraction: 0.9\n"
      "  colour: red\n"
      "  {a: 1}: 2\n");
  n["overrun"].reject_unknown_keys({"warn_fraction", "error_fraction"});
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 3);
  CHECK(errors[0] ==
        at(2, 3, "overrun.warn_fractoin", "unknown key; did you mean 'warn_fraction'?"));
  CHECK(errors[1] ==
        at(4, 3, "overrun.colour", "unknown key; expected one of: warn_fraction, error_fraction"));
  CHECK(errors[2] == at(5, 3, "overrun", "a key must be a name, got a mapping"));
}

TEST_CASE("reject_unknown_keys takes any range of names and ignores absent sections",
          "[config][node]") {
  const Node n = load("a: 1\nb: 2\n");
  constexpr std::array<std::string_view, 2> kKeys{"a", "b"};
  n.reject_unknown_keys(kKeys);
  const std::vector<std::string> from_registry{"a", "b"};
  n.reject_unknown_keys(from_registry);
  n["absent"].reject_unknown_keys({"x"});
  CHECK_FALSE(n.has_errors());
  const Node m = load("s: {k: 1}\n");
  m["s"].reject_unknown_keys({});
  CHECK(only_error(m) == at(1, 5, "s.k", "unknown key; this mapping takes no keys"));
}

TEST_CASE("entries and elements build dotted and indexed paths", "[config][node]") {
  const Node n = load(
      "monitor:\n"
      "  components:\n"
      "    motor:\n"
      "      overrun: {warn_fraction: high}\n"
      "    arm: {}\n"
      "filters:\n"
      "  - {id: 0x10}\n"
      "  - {id: twelve}\n"
      "empty_map:\n"
      "empty_list: []\n");
  std::vector<std::string> names;
  for (const auto& [name, component] : n["monitor"]["components"].entries()) {
    names.push_back(name);
    (void)component["overrun"].optional("warn_fraction", 0.5);
  }
  CHECK(names == std::vector<std::string>{"motor", "arm"});
  std::vector<std::uint32_t> ids;
  for (const Node& f : n["filters"].elements()) ids.push_back(f.required<std::uint32_t>("id"));
  CHECK(ids == std::vector<std::uint32_t>{16, 0});
  CHECK(n["empty_map"].entries().empty());
  CHECK(n["empty_list"].elements().empty());
  CHECK(n["absent"].elements().empty());
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 2);
  CHECK(errors[0] == at(4, 32, "monitor.components.motor.overrun.warn_fraction",
                        "expected a number, got 'high'"));
  CHECK(errors[1] == at(8, 10, "filters[1].id", "expected an integer, got 'twelve'"));
}

TEST_CASE("Sequence elements with bad values are reported at their index", "[config][node]") {
  const Node n = load("ids: [1, x, 3, y]\n");
  CHECK(n.required<std::vector<int>>("ids").empty());
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 2);
  CHECK(errors[0] == at(1, 10, "ids[1]", "expected an integer, got 'x'"));
  CHECK(errors[1] == at(1, 16, "ids[3]", "expected an integer, got 'y'"));
  const Node m = load("ids: 5\n");
  (void)m.required<std::vector<int>>("ids");
  CHECK(only_error(m) == at(1, 6, "ids", "expected a sequence, got '5'"));
}

TEST_CASE("Reading below a scalar reports 'expected a mapping' once", "[config][node]") {
  const Node n = load("monitor: 5\n");
  const Node m = n["monitor"];
  (void)m.required<int>("period");
  (void)m.required<int>("priority");
  (void)m["deep"].optional("x", 1);
  (void)m.entries();
  CHECK(only_error(n) == at(1, 10, "monitor", "expected a mapping, got '5'"));
  CHECK_FALSE(m["period"].defined());
}

TEST_CASE("at() reports a missing section once and silences the keys below it", "[config][node]") {
  const Node n = load("other: 1\n");
  const Node m = n.at("monitor");
  (void)m.required<int>("period");
  (void)m.required_duration("timeout");
  CHECK(only_error(n) == at(1, 1, "monitor", "required key is missing"));
  // operator[] instead reports every required key below the missing section.
  const Node o = load("other: 1\n");
  (void)o["monitor"].required<int>("period");
  (void)o["monitor"].required<int>("priority");
  const ConfigErrors errors = o.errors();
  REQUIRE(errors.size() == 2);
  CHECK(errors[0] == at(1, 1, "monitor.period", "required key is missing"));
  CHECK(errors[1] == at(1, 1, "monitor.priority", "required key is missing"));
}

TEST_CASE("Durations and periods are read with units and located errors", "[config][node]") {
  const Node n = load(
      "period: 1 kHz\n"         // 1
      "timeout: 2.5ms\n"        // 2
      "timeout_ms: 5\n"         // 3
      "bad_unit: 10 parsecs\n"  // 4
      "bare: 5\n"               // 5
      "negative: -1ms\n"        // 6
      "list: [1ms]\n"           // 7
      "zero: 0ms\n");           // 8
  CHECK(n.required_period("period") == kNanosPerMilli);
  CHECK(n.required_duration("timeout") == 2'500'000);
  CHECK(n.required_duration("timeout_ms", TimeUnit::Millis) == 5 * kNanosPerMilli);
  CHECK(n.optional_duration("absent", 3 * kNanosPerMicro) == 3 * kNanosPerMicro);
  CHECK(n.optional_duration("absent", 1, TimeUnit::Millis) == 1);
  CHECK(n.optional_period("absent", 9) == 9);
  CHECK(n.optional_period("timeout", 9) == 2'500'000);
  CHECK(n.optional_period("timeout_ms", 9, TimeUnit::Micros) == 5'000);
  CHECK(n["timeout"].get_duration() == 2'500'000);
  CHECK(n["timeout_ms"].get_period(TimeUnit::Nanos) == 5);
  CHECK_FALSE(n.has_errors());
  (void)n.required_duration("bad_unit");
  (void)n.required_duration("bare");
  (void)n.required_duration("negative");
  (void)n.required_period("list");
  (void)n.required_duration("zero", positive());
  (void)n.required_duration("missing");
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 6);
  CHECK(errors[0] == at(1, 1, "missing", "required key is missing"));
  CHECK(errors[1] ==
        at(4, 11, "bad_unit", "'10 parsecs' has an unknown unit 'parsecs'; use ns, us, ms or s"));
  CHECK(errors[2] == at(5, 7, "bare", "'5' has no unit; use ns, us, ms or s (e.g. '5ms')"));
  CHECK(errors[3] == at(6, 11, "negative", "'-1ms' is negative; a duration must be zero or more"));
  CHECK(errors[4] == at(7, 7, "list", "expected a period such as '1ms' or '1kHz', got a sequence"));
  CHECK(errors[5] == at(8, 7, "zero", "must be positive, got '0ms'"));
}

TEST_CASE("Columns count characters, not bytes", "[config][node]") {
  const Node n = load("mot\u00f6r: {period: 5 parsecs}\n");
  (void)n["mot\u00f6r"].required_duration("period");
  const ConfigError e = only_error(n);
  CHECK(e.line == 1);
  CHECK(e.column == 17);  // yaml-cpp counts 18: 'ö' is two bytes
  CHECK(e.field == "mot\u00f6r.period");
}

TEST_CASE("Node::error records schema-level problems and finish collects them", "[config][node]") {
  const Node n = load(
      "warn: 0.9\n"
      "error: 0.5\n");
  struct Limits {
    double warn;
    double error;
  };
  const Limits l{n.required<double>("warn"), n.required<double>("error")};
  auto ok = n.finish(l);
  REQUIRE(ok.has_value());
  CHECK(ok->warn == 0.9);
  if (l.warn > l.error) n["warn"].error("must not exceed error (0.5)");
  auto bad = n.finish(l);
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error() == ConfigErrors{at(1, 7, "warn", "must not exceed error (0.5)")});
}

TEST_CASE("Errors come back in file order whatever order they were found in", "[config][node]") {
  const Node n = load("a: x\nb: y\nc: z\n");
  (void)n.required<int>("c");
  (void)n.required<int>("a");
  (void)n.required<int>("b");
  const ConfigErrors errors = n.errors();
  REQUIRE(errors.size() == 3);
  CHECK(errors[0].line == 1);
  CHECK(errors[1].line == 2);
  CHECK(errors[2].line == 3);
}

TEST_CASE("A default-constructed Node is an empty document", "[config][node]") {
  const Node n;
  CHECK(n.defined());
  CHECK(n.is_null());
  CHECK(n.optional("x", 3) == 3);
  CHECK(n.entries().empty());
  CHECK_FALSE(n.has_errors());
  (void)n.required<int>("x");
  CHECK(only_error(n) == ConfigError{"", 0, 0, "x", "required key is missing"});
}

TEST_CASE("Inspection reports kind, path and location", "[config][node]") {
  const Node n = load("a:\n  b: [1]\n  c: s\n");
  CHECK(n.is_mapping());
  CHECK(n["a"].has("b"));
  CHECK_FALSE(n["a"].has("z"));
  CHECK(n["a"]["b"].is_sequence());
  CHECK(n["a"]["c"].is_scalar());
  CHECK(n["a"]["c"].path() == "a.c");
  CHECK(n["a"]["c"].line() == 3);
  CHECK(n["a"]["c"].column() == 6);
  CHECK(n.file() == "t.yaml");
  CHECK(n["a"]["c"].yaml().Scalar() == "s");
  CHECK_FALSE(n["z"].defined());
}
