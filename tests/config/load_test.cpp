#include "vigil/config/load.hpp"

#include <array>
#include <catch2/catch.hpp>
#include <map>
#include <stdexcept>
#include <string>

using namespace vigil::config;
using vigil::kNanosPerMilli;
using vigil::Nanos;

namespace {

const std::string kData = VIGIL_CONFIG_TEST_DATA;

std::string data(const std::string& name) { return kData + "/" + name; }

// A schema of the kind the monitor will have: thresholds with per-component overrides.
enum class Policy { Fifo, Other };
constexpr std::array<EnumName<Policy>, 2> kPolicies{
    {{"FIFO", Policy::Fifo}, {"OTHER", Policy::Other}}};

struct Overrun {
  double warn_fraction = 0;
  double error_fraction = 0;
};
struct Component {
  bool enabled = true;
  Overrun overrun;
};
struct Monitor {
  Nanos period_ns = 0;
  Policy policy = Policy::Other;
  int priority = 0;
  std::map<std::string, Component> components;
};

vigil::expected<Monitor, ConfigErrors> load_monitor(const Node& root) {
  root.reject_unknown_keys({"monitor"});
  const Node m = root.at("monitor");
  m.reject_unknown_keys({"period", "policy", "priority", "components"});
  Monitor out;
  out.period_ns = m.required_period("period", positive());
  out.policy = m.required_enum("policy", kPolicies);
  out.priority = m.optional("priority", 50, in_range(1, 99));
  for (const auto& [name, c] : m["components"].entries()) {
    c.reject_unknown_keys({"enabled", "overrun"});
    Component& comp = out.components[name];
    comp.enabled = c.optional("enabled", true);
    const Node o = c.at("overrun");
    o.reject_unknown_keys({"warn_fraction", "error_fraction"});
    comp.overrun.warn_fraction = o.required<double>("warn_fraction", in_range(0.0, 1.0));
    comp.overrun.error_fraction = o.required<double>("error_fraction", in_range(0.0, 1.0));
    if (comp.overrun.warn_fraction > comp.overrun.error_fraction) {
      o["warn_fraction"].error("must not exceed error_fraction");
    }
  }
  return root.finish(std::move(out));
}

}  // namespace

TEST_CASE("A valid file loads through a schema loader", "[config][load]") {
  const auto monitor = load_file(data("monitor_ok.yaml"), load_monitor);
  INFO((monitor ? std::string() : to_string(monitor.error())));
  REQUIRE(monitor.has_value());
  CHECK(monitor->period_ns == kNanosPerMilli);
  CHECK(monitor->policy == Policy::Fifo);
  CHECK(monitor->priority == 80);
  REQUIRE(monitor->components.size() == 2);
  CHECK(monitor->components.at("motor").enabled);
  CHECK(monitor->components.at("motor").overrun.error_fraction == 0.9);
  CHECK_FALSE(monitor->components.at("arm").enabled);
  CHECK(monitor->components.at("arm").overrun.warn_fraction == 0.25);
}

TEST_CASE("Every error of a document is collected, each at its exact location", "[config][load]") {
  const std::string file = data("monitor_errors.yaml");
  const auto monitor = load_file(file, load_monitor);
  REQUIRE_FALSE(monitor.has_value());
  const ConfigErrors expected{
      {file, 3, 11, "monitor.period",
       "'10 parsecs' has an unknown unit 'parsecs'; use ns, us, ms, s, Hz, kHz or MHz"},
      {file, 4, 3, "monitor.max_reports",
       "unknown key; expected one of: period, policy, priority, components"},
      {file, 5, 11, "monitor.policy", "'FIFOO' is not one of FIFO, OTHER; did you mean 'FIFO'?"},
      {file, 6, 13, "monitor.priority", "must be between 1 and 99, got '120'"},
      {file, 10, 24, "monitor.components.motor.overrun.warn_fraction",
       "expected a number, got 'abc'"},
      {file, 11, 25, "monitor.components.motor.overrun.error_fraction",
       "must be between 0 and 1, got '1.5'"},
      {file, 13, 16, "monitor.components.arm.enabled", "expected true or false, got 'yes'"},
      {file, 14, 16, "monitor.components.arm.overrun.warn_fraction", "required key is missing"},
      {file, 14, 17, "monitor.components.arm.overrun.warn_fractoin",
       "unknown key; did you mean 'warn_fraction'?"},
  };
  INFO(to_string(monitor.error()));
  CHECK(monitor.error() == expected);
  CHECK(monitor.error()[4].to_string() ==
        file +
            ":10:24: monitor.components.motor.overrun.warn_fraction: expected a number, got "
            "'abc'");
}

TEST_CASE("Duplicate keys are reported at each repetition", "[config][load]") {
  const std::string file = data("duplicates.yaml");
  const auto root = load_file(file);
  REQUIRE_FALSE(root.has_value());
  const ConfigErrors expected{
      {file, 5, 3, "limits.warn", "duplicate key (first defined at line 3, column 3)"},
      {file, 6, 1, "period", "duplicate key (first defined at line 1, column 1)"},
  };
  CHECK(root.error() == expected);
}

TEST_CASE("Duplicate keys are found in flow mappings and inside sequences", "[config][load]") {
  const auto root = load_string("items:\n  - {a: 1, b: 2, a: 3}\n", "d.yaml");
  REQUIRE_FALSE(root.has_value());
  CHECK(root.error() == ConfigErrors{{"d.yaml", 2, 18, "items[0].a",
                                      "duplicate key (first defined at line 2, column 6)"}});
}

TEST_CASE("Aliases load, and a recursive one is refused where it is written", "[config][load]") {
  const auto shared = load_string("base: &b {x: 1}\nother: *b\n", "a.yaml");
  REQUIRE(shared.has_value());
  CHECK((*shared)["other"].required<int>("x") == 1);
  // A cycle would make every reader of the document loop: refused (limits_test.cpp has more).
  const auto cyclic = load_string("a: &x [1, *x]\n", "c.yaml");
  REQUIRE_FALSE(cyclic.has_value());
  CHECK(cyclic.error()[0].line == 1);
  CHECK(cyclic.error()[0].column == 11);
}

TEST_CASE("A syntax error is reported at yaml-cpp's location", "[config][load]") {
  const std::string file = data("syntax_error.yaml");
  const auto root = load_file(file);
  REQUIRE_FALSE(root.has_value());
  CHECK(root.error() == ConfigErrors{{file, 4, 8, "", "end of sequence flow not found"}});
  const auto inline_error = load_string("a: b: c\n", "s.yaml");
  REQUIRE_FALSE(inline_error.has_value());
  CHECK(vigil::config::to_string(inline_error.error()) == "s.yaml:1:5: illegal map value");
}

TEST_CASE("A missing file is reported with its path and the system's reason", "[config][load]") {
  const std::string file = data("does_not_exist.yaml");
  const auto root = load_file(file);
  REQUIRE_FALSE(root.has_value());
  CHECK(root.error() ==
        ConfigErrors{{file, 0, 0, "", "cannot read file: No such file or directory"}});
  CHECK(root.error()[0].to_string() == file + ": cannot read file: No such file or directory");
  const auto directory = load_file(kData);
  REQUIRE_FALSE(directory.has_value());
  CHECK(directory.error()[0].message == "cannot read file: Is a directory");
}

TEST_CASE("An empty file is an empty mapping: defaults apply, required keys are missing",
          "[config][load]") {
  const std::string file = data("empty.yaml");
  const auto root = load_file(file);
  REQUIRE(root.has_value());
  CHECK(root->is_null());
  CHECK(root->optional("priority", 5) == 5);
  const auto monitor = load_file(file, load_monitor);
  REQUIRE_FALSE(monitor.has_value());
  CHECK(monitor.error() == ConfigErrors{{file, 0, 0, "monitor", "required key is missing"}});
}

TEST_CASE("A file with two documents is rejected", "[config][load]") {
  const std::string file = data("two_documents.yaml");
  const auto root = load_file(file);
  REQUIRE_FALSE(root.has_value());
  CHECK(root.error() ==
        ConfigErrors{
            {file, 3, 1, "", "a file must hold a single YAML document; a second one starts here"}});
}

TEST_CASE("A loader cannot succeed past errors it recorded or swallow an exception",
          "[config][load]") {
  // Returns a value although a key was bad: the recorded error still fails the load.
  const auto careless =
      load_string("n: abc\n", "l.yaml", [](const Node& root) { return root.optional("n", 3); });
  REQUIRE_FALSE(careless.has_value());
  CHECK(careless.error() == ConfigErrors{{"l.yaml", 1, 4, "n", "expected an integer, got 'abc'"}});

  const auto throwing = load_string(
      "n: 1\n", "l.yaml", [](const Node&) -> int { throw std::runtime_error("database offline"); });
  REQUIRE_FALSE(throwing.has_value());
  CHECK(throwing.error() ==
        ConfigErrors{{"l.yaml", 0, 0, "", "the loader failed: database offline"}});

  const auto silent = load_string("n: 1\n", "l.yaml", [](const Node&) {
    return vigil::expected<int, ConfigErrors>(vigil::unexpected<ConfigErrors>(ConfigErrors{}));
  });
  REQUIRE_FALSE(silent.has_value());
  CHECK(silent.error().size() == 1);

  const auto own = load_string("n: 1\n", "l.yaml", [](const Node& root) {
    return vigil::expected<int, ConfigErrors>(vigil::unexpected<ConfigErrors>(
        ConfigErrors{{root.file(), 1, 1, "n", "rejected by the schema"}}));
  });
  REQUIRE_FALSE(own.has_value());
  CHECK(own.error() == ConfigErrors{{"l.yaml", 1, 1, "n", "rejected by the schema"}});

  const auto plain =
      load_string("n: 4\n", "l.yaml", [](const Node& root) { return root.required<int>("n") * 2; });
  REQUIRE(plain.has_value());
  CHECK(*plain == 8);
}
