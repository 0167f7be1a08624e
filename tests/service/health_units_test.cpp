#include "vigil/service/health_units.hpp"

#include <catch2/catch.hpp>
#include <chrono>
#include <thread>

#include "vigil/service/supervision_service.hpp"

using namespace vigil;

TEST_CASE("A supervision's unit: its status, state and figures under their names",
          "[service][health]") {
  health::SupervisionReport s;
  s.name = "sense_to_act";
  s.kind = health::SupervisionKind::Deadline;
  s.status = health::SupervisionStatus::Expired;
  s.entities = {"camera", "drive"};
  s.checkpoints = 40;
  s.evaluations = 19;
  s.failures = 1;
  s.failed_count = 1;
  s.expirations = 1;
  s.last_duration_ns = 1'500'000;
  s.min_duration_ns = 900'000;
  s.max_duration_ns = 1'800'000;
  s.has_failure = true;
  s.last_failure.failure = health::FailureKind::DeadlineMissed;
  s.last_failure.fault_ns = 10'000'000;
  s.last_failure.detected_ns = 10'250'000;
  s.last_failure.text = "deadline 'sense_to_act' expired: deadline_missed: no drive.write";
  const Report r = service::supervision_unit(s);
  CHECK(r.kind == ReportKind::Unit);
  CHECK(r.kind_name() == "supervision");
  CHECK(r.name == "supervision sense_to_act");
  CHECK(r.state_label == "expired");
  CHECK(r.status.level() == StatusLevel::Error);
  CHECK(r.status.summary().find("deadline_missed") != std::string::npos);
  REQUIRE(r.field("type") != nullptr);
  CHECK(r.field("type")->text == "deadline");
  CHECK(r.field("entities")->text == "camera, drive");
  CHECK(r.field("evaluations")->count == 19);
  CHECK(r.field("max")->duration_ns == 1'800'000);
  CHECK(r.field("last_failure")->text == "deadline_missed");
  CHECK(r.field("detected_after")->duration_ns == 250'000);
  CHECK(r.field("last_cycle") == nullptr);  // an alive supervision's figure

  // FAILED is WARN; DEACTIVATED (stopped on purpose) is OK, without a message.
  s.status = health::SupervisionStatus::Failed;
  CHECK(service::supervision_unit(s).status.level() == StatusLevel::Warn);
  s.status = health::SupervisionStatus::Deactivated;
  s.has_failure = false;
  const Report idle = service::supervision_unit(s);
  CHECK(idle.status.level() == StatusLevel::Ok);
  CHECK(idle.status.messages().empty());
  CHECK(idle.state_label == "deactivated");
  CHECK(idle.field("last_failure") == nullptr);
}

TEST_CASE("The service shows every health supervision as a unit of its cycles",
          "[service][health]") {
  ComponentRegistry reg;
  SupervisionService service({.registry = &reg, .monitor_thread = false});
  health::HealthConfig cfg;
  cfg.alive.push_back({.name = "ghost_alive",
                       .checkpoint = {"ghost"},
                       .reference_cycle_ns = 10 * kNanosPerMilli,
                       .expected_indications = 10,
                       .startup_grace_ns = 50 * kNanosPerMilli});
  REQUIRE(service.aggregator().supervise_health(cfg).has_value());
  REQUIRE(service.start());
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const ReportSet reports = service.stop();
  const Report* ghost = reports.find("supervision ghost_alive");
  REQUIRE(ghost != nullptr);
  CHECK(ghost->kind_name() == "supervision");
  CHECK(ghost->state_label == "expired");  // it never started within its grace period
  CHECK(ghost->status.level() == StatusLevel::Error);
  REQUIRE(ghost->field("last_failure") != nullptr);
  CHECK(ghost->field("last_failure")->text == "never_started");
  CHECK(reports.worst() == StatusLevel::Error);

  // Without supervisions, no unit.
  SupervisionService plain({.registry = &reg, .monitor_thread = false});
  REQUIRE(plain.start());
  const ReportSet none = plain.stop();
  for (const Report& r : none.components) CHECK_FALSE(r.is_unit("supervision"));
}
