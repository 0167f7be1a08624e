// Deployment extensions: sections looked up by a registered name (vigil/deploy/extension.hpp).
#include "vigil/deploy/extension.hpp"

#include <catch2/catch.hpp>
#include <mutex>
#include <vector>

#include "vigil/deploy/system.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {

class Idle : public Task<Idle> {
 public:
  explicit Idle(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};

ComponentFactory& factory() {
  static ComponentFactory f;
  static const bool once = f.add<Idle>("test.idle");
  (void)once;
  return f;
}

std::vector<std::string>& calls() {
  static std::vector<std::string> c;
  return c;
}

// An extension configured by `counter: {value: N}`: reports one component named after N.
class Counter : public Extension {
 public:
  explicit Counter(int value) : value_(value) {}
  expected<void, Error> start() override {
    calls().push_back("start");
    return {};
  }
  void stopping() override { calls().push_back("stopping"); }
  void stop() override { calls().push_back("stop"); }
  void contribute(exporter::Snapshot& snapshot) override {
    Report r;
    r.name = "counter" + std::to_string(value_);
    snapshot.reports.components.push_back(r);
  }
  int value() const { return value_; }

 private:
  int value_;
};

void register_counter() {
  register_extension("counter",
                     [](const config::Node& section,
                        System&) -> expected<std::unique_ptr<Extension>, config::ConfigErrors> {
                       section.reject_unknown_keys({"value"});
                       const int v = section.required<int>("value", config::in_range(0, 100));
                       if (section.has_errors()) return vigil::unexpected(section.errors());
                       return std::make_unique<Counter>(v);
                     });
}

constexpr const char* kBase = R"(
activities: [{name: a, period: 5ms}]
components: [{name: c, type: test.idle, activity: a}]
supervision: {lock_memory: false, monitor_period: 50ms}
)";

}  // namespace

TEST_CASE("A section is accepted only when an extension is registered under its name",
          "[deploy][extension]") {
  // No extension "lidar" exists: the section is refused with what the program knows.
  auto d = load_deployment_string(std::string(kBase) + "lidar: {device: /dev/ttyUSB0}\n", "d.yaml",
                                  factory());
  REQUIRE_FALSE(d.has_value());
  const std::string e = config::to_string(d.error());
  CHECK_THAT(e,
             Catch::StartsWith("d.yaml:5:8: lidar: unknown section 'lidar': not a deployment "
                               "key (name, activities, components, supervision, outputs, health, "
                               "diagnosis, reactions) and "
                               "no extension handles it in this program (registered: "));
  // A typo of a known key still gets a suggestion.
  auto typo = load_deployment_string(std::string(kBase) + "supervison: {}\n", "d.yaml", factory());
  REQUIRE_FALSE(typo.has_value());
  CHECK_THAT(config::to_string(typo.error()), Catch::Contains("did you mean 'supervision'?"));

  register_counter();
  CHECK(find_extension("counter"));
  CHECK_FALSE(find_extension("lidar"));
  const auto names = registered_extensions();
  CHECK(std::find(names.begin(), names.end(), "counter") != names.end());
  auto ok =
      load_deployment_string(std::string(kBase) + "counter: {value: 7}\n", "d.yaml", factory());
  REQUIRE(ok.has_value());
  REQUIRE(ok->extensions.size() == 1);
  CHECK(ok->extensions[0].name == "counter");
  CHECK(ok->extensions[0].node.required<int>("value") == 7);
}

TEST_CASE("System builds each section's extension by name and runs it with the system",
          "[deploy][extension]") {
  register_counter();
  calls().clear();
  auto spec =
      load_deployment_string(std::string(kBase) + "counter: {value: 7}\n", "d.yaml", factory());
  REQUIRE(spec.has_value());
  auto sys = System::create(std::move(*spec), factory());
  REQUIRE(sys.has_value());
  Counter* c = (*sys)->extension<Counter>();
  REQUIRE(c != nullptr);
  CHECK(c->value() == 7);
  REQUIRE((*sys)->start().has_value());
  (*sys)->stop();
  CHECK(calls() == std::vector<std::string>{"start", "stopping", "stop"});
  CHECK((*sys)->step_monitor().find("counter7") != nullptr);

  // The maker's errors are the System's, located in the file.
  auto bad =
      load_deployment_string(std::string(kBase) + "counter: {value: 700}\n", "d.yaml", factory());
  REQUIRE(bad.has_value());  // the loader does not read an extension's section
  auto refused = System::create(std::move(*bad), factory());
  REQUIRE_FALSE(refused.has_value());
  CHECK_THAT(config::to_string(refused.error()),
             Catch::StartsWith("d.yaml:5:18: counter.value: must be between 0 and 100"));
}
