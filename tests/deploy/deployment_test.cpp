#include "vigil/deploy/deployment.hpp"

#include <catch2/catch.hpp>
#include <utility>

#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::deploy;

namespace {
class Dummy : public Task<Dummy> {
 public:
  explicit Dummy(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        gain(c.parameters.defined() ? c.parameters.optional("gain", 1.0, config::positive())
                                    : 1.0) {}
  void on_update() {}
  double gain;
};

ComponentFactory& test_factory() {
  static ComponentFactory f;
  static const bool once = f.add<Dummy>("test.dummy", "does nothing");
  (void)once;
  return f;
}

// The smallest deployment: one activity, one component (a test adds its `supervision:` line 3).
constexpr const char* kOneComponent = R"(activities: [{name: a, period: 1ms}]
components: [{name: x, type: test.dummy, activity: a}]
)";

std::string errors_of(std::string_view yaml) {
  auto d = load_deployment_string(yaml, "d.yaml", test_factory());
  REQUIRE_FALSE(d.has_value());
  return config::to_string(d.error());
}
}  // namespace

namespace {
class Registered : public Task<Registered> {
 public:
  explicit Registered(const ComponentContext& c) : Task(c.name, c.supervision, c.registry()) {}
  void on_update() {}
};
}  // namespace
VIGIL_REGISTER_COMPONENT(Registered, "test.registered");  // the one registration line

TEST_CASE("VIGIL_REGISTER_COMPONENT registers a type in the process's factory in one line",
          "[deploy][factory]") {
  const auto* t = ComponentFactory::instance().find("test.registered");
  REQUIRE(t != nullptr);
  Registry<task::Message> reg;
  ComponentContext ctx{"r", {}, {}, &reg, nullptr};
  const auto task = t->make(ctx);
  REQUIRE(task != nullptr);
  CHECK(task->name() == "r");
  CHECK_FALSE(ComponentFactory::instance().add<Registered>("test.registered"));  // taken
}

TEST_CASE("A deployment parses activities, components, supervision and outputs",
          "[deploy][deployment]") {
  auto d = load_deployment_string(R"(
name: cell
activities:
  - {name: fast, period: 1 kHz, policy: FIFO, priority: 90, cpu: 0, overrun: catch_up,
     overrun_limit: {overruns: 5, window: 100}}
  - {name: slow, period: 100ms, share_thread: false}
components:
  - {name: a, type: test.dummy, activity: fast, detectors: [allocation, page_faults]}
  - {name: b, type: test.dummy, activity: slow, overhead_sample_every: 1,
     parameters: {gain: 3}}
supervision: {supervisor_period: 5ms, monitor_period: 2s, ewma_weight: 0.2,
              thresholds: {defaults: {overrun: {near_fraction: 0.7}}}}
outputs: {json: out.json}
)",
                                  "d.yaml", test_factory());
  REQUIRE(d.has_value());
  CHECK(d->name == "cell");
  REQUIRE(d->activities.size() == 2);
  const auto& fast = d->activities[0].config;
  CHECK(fast.period_ns == kNanosPerMilli);
  CHECK(fast.policy == SchedPolicy::Fifo);
  CHECK(fast.priority == 90);
  CHECK(fast.cpu == 0);
  CHECK(fast.overrun_policy == OverrunPolicy::CatchUp);
  CHECK(fast.overrun_limit.max_overruns == 5);
  CHECK(fast.overrun_limit.window_cycles == 100);
  CHECK_FALSE(d->activities[1].config.share_thread);
  REQUIRE(d->components.size() == 2);
  CHECK(d->components[0].supervision.detectors == (Detectors::Allocation | Detectors::PageFaults));
  CHECK(d->components[1].supervision.overhead_sample_every == 1);
  CHECK(d->supervision.supervisor_period_ns == 5 * kNanosPerMilli);
  CHECK(d->supervision.monitor_period_ns == 2 * kNanosPerSecond);
  CHECK(d->supervision.ewma_weight == Approx(0.2));
  CHECK(d->supervision.thresholds.defaults.overrun.near_fraction == Approx(0.7));
  REQUIRE(d->outputs.json.has_value());
  CHECK(d->outputs.json->string() == "out.json");
}

TEST_CASE("Deployment errors name file:line:col and every error is reported",
          "[deploy][deployment]") {
  const std::string e = errors_of(R"(activities:
  - {name: a, period: 1ms}
  - {name: a, period: -1ms}
components:
  - {name: x, type: test.dumy, activity: a}
  - {name: y, type: test.dummy, activity: b, colour: red}
)");
  CHECK_THAT(e, Catch::Contains("d.yaml:3:12: activities[1].name: activity 'a' is defined twice"));
  CHECK_THAT(e, Catch::Contains("d.yaml:3:23: activities[1].period: '-1ms' is negative"));
  CHECK_THAT(
      e, Catch::Contains("d.yaml:5:21: components[0].type: unknown component type 'test.dumy'; did "
                         "you mean 'test.dummy'?"));
  CHECK_THAT(e, Catch::Contains("d.yaml:6:46: components[1].colour: unknown key"));
  CHECK_THAT(e, Catch::Contains(
                    "d.yaml:6:43: components[1].activity: no activity named 'b' (defined: a)"));
}

TEST_CASE("A deployment needs components, and activities for them", "[deploy][deployment]") {
  CHECK_THAT(errors_of("activities: []\ncomponents: []\n"),
             Catch::Contains("a deployment needs at least one component"));
  CHECK_THAT(errors_of("components:\n  - {name: x, type: test.dummy, activity: a}\n"),
             Catch::Contains("activities: required key is missing"));
  CHECK_THAT(errors_of("- 1\n- 2\n"), Catch::Contains("a deployment is a mapping"));
}

TEST_CASE("supervision.clock selects the process's clock, and an unknown one is an error",
          "[deploy][deployment][tsc]") {
  const std::string base = kOneComponent;
  auto d = load_deployment_string(base, "d.yaml", test_factory());
  REQUIRE(d.has_value());
  CHECK(d->supervision.clock == platform::ClockSource::Monotonic);
  auto t = load_deployment_string(base + "supervision: {clock: tsc}\n", "d.yaml", test_factory());
  REQUIRE(t.has_value());
  CHECK(t->supervision.clock == platform::ClockSource::Tsc);
  const std::string e = errors_of(base + "supervision: {clock: rdtsc}\n");
  CHECK_THAT(e, Catch::Contains("d.yaml:3:22: supervision.clock"));
  CHECK_THAT(e, Catch::Contains("rdtsc"));
}

TEST_CASE("flight_recorder.stores selects how rings are written, and an unknown one is an error",
          "[deploy][deployment]") {
  const std::string base = kOneComponent;
  auto d = load_deployment_string(base, "d.yaml", test_factory());
  REQUIRE(d.has_value());
  CHECK(d->supervision.recorder.stores == supervisor::RingStores::Auto);
  auto s = load_deployment_string(base + "supervision: {flight_recorder: {stores: streaming}}\n",
                                  "d.yaml", test_factory());
  REQUIRE(s.has_value());
  CHECK(s->supervision.recorder.stores == supervisor::RingStores::Streaming);
  const std::string e = errors_of(base + "supervision: {flight_recorder: {stores: fast}}\n");
  CHECK_THAT(e, Catch::Contains("d.yaml:3:41: supervision.flight_recorder.stores"));
  CHECK_THAT(e, Catch::Contains("fast"));
}

TEST_CASE("flight_recorder.pages selects where rings live, and an unknown one is an error",
          "[deploy][deployment]") {
  const std::string base = kOneComponent;
  auto d = load_deployment_string(base, "d.yaml", test_factory());
  REQUIRE(d.has_value());
  CHECK(d->supervision.recorder.pages == supervisor::RingPages::Auto);
  for (const auto& [word, pages] : {std::pair{"huge", supervisor::RingPages::Huge},
                                    std::pair{"ordinary", supervisor::RingPages::Ordinary}}) {
    auto s = load_deployment_string(
        base + "supervision: {flight_recorder: {pages: " + word + "}}\n", "d.yaml", test_factory());
    REQUIRE(s.has_value());
    CHECK(s->supervision.recorder.pages == pages);
  }
  const std::string e = errors_of(base + "supervision: {flight_recorder: {pages: large}}\n");
  CHECK_THAT(e, Catch::Contains("d.yaml:3:40: supervision.flight_recorder.pages"));
  CHECK_THAT(e, Catch::Contains("large"));
  CHECK_THAT(e, Catch::Contains("auto, huge, ordinary"));
}

TEST_CASE("overhead_sample_every takes any count, and a bad one is an error naming the field",
          "[deploy][deployment]") {
  auto d = load_deployment_string(R"(activities: [{name: a, period: 1ms}]
components: [{name: x, type: test.dummy, activity: a, overhead_sample_every: 48}]
)",
                                  "d.yaml", test_factory());
  REQUIRE(d.has_value());
  CHECK(d->components[0].supervision.overhead_sample_every == 48);
  const std::string e = errors_of(R"(activities: [{name: a, period: 1ms}]
components: [{name: x, type: test.dummy, activity: a, overhead_sample_every: -3}]
)");
  CHECK_THAT(e, Catch::Contains("d.yaml:2:78: components[0].overhead_sample_every"));
}
