// Threads shared by several components as units of the diagnosis graph.
#include <catch2/catch.hpp>

#include "vigil/monitor/diagnosis.hpp"
#include "vigil/service/thread_units.hpp"

using namespace vigil;
using namespace vigil::monitor;

namespace {

Report component(std::string name, int tid, Nanos silence_ns, Nanos deadline_ns = 30'000'000) {
  Report r;
  r.kind = ReportKind::Component;
  r.name = std::move(name);
  r.activity = "control";
  r.tid = tid;
  r.period_ns = kNanosPerMilli;
  r.state = TaskState::Running;
  r.silence_ns = silence_ns;
  r.deadline_ns = deadline_ns;
  if (silence_ns > deadline_ns) r.merge(StatusLevel::Error, "deadline: no cycle");
  return r;
}

}  // namespace

TEST_CASE("A shared thread is a unit: OK while one component cycles, the root cause when stuck",
          "[service][threads]") {
  ReportSet set;
  set.components.push_back(component("alone", 7, 0));
  set.components.push_back(component("motor_left", 9, 1'000'000));
  set.components.push_back(component("motor_right", 9, 2'000'000));
  vigil::service::add_thread_units(set);
  REQUIRE(set.components.size() == 4);  // no unit for a thread with one component
  const Report* t = set.find("thread control (tid 9)");
  REQUIRE(t != nullptr);
  CHECK(t->is_unit("thread"));
  CHECK(t->status.ok());
  CHECK(set.find("motor_left")->depends_on == std::vector<std::string>{"thread control (tid 9)"});
  CHECK(set.find("alone")->depends_on.empty());

  ReportSet stuck;
  stuck.components.push_back(component("motor_left", 9, 3'000'000'000));
  stuck.components.push_back(component("motor_right", 9, 3'001'000'000));
  vigil::service::add_thread_units(stuck);
  const Report* u = stuck.find("thread control (tid 9)");
  REQUIRE(u != nullptr);
  CHECK(u->status.level() == StatusLevel::Error);
  CHECK_THAT(u->status.summary(), Catch::Contains("none of its 2 components cycled for 3.00s") &&
                                      Catch::Contains("the last to end a cycle: motor_left"));
  DiagnosisGraph graph;
  graph.apply(stuck, 0);
  CHECK(stuck.root_causes == std::vector<std::string>{"thread control (tid 9)"});
  CHECK(stuck.find("motor_right")->caused_by == std::vector<std::string>{"thread control (tid 9)"});
}

TEST_CASE("A thread whose components are not all silent is not stuck", "[service][threads]") {
  ReportSet set;
  set.components.push_back(component("a", 9, 3'000'000'000));
  set.components.push_back(component("b", 9, 1'000'000));  // still cycles
  Report stopped = component("c", 9, -1);
  stopped.state = TaskState::Stopped;
  set.components.push_back(stopped);
  vigil::service::add_thread_units(set);
  const Report* u = set.find("thread control (tid 9)");
  REQUIRE(u != nullptr);
  CHECK(u->status.ok());
  CHECK(u->field("components")->count == 3);
}
