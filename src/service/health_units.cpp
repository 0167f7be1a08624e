#include "vigil/service/health_units.hpp"

#include <string>
#include <utility>

#include "vigil/export/output.hpp"
#include "vigil/monitor/health.hpp"

namespace vigil::service {

namespace {

// The figures only one kind of supervision has.
void add_kind_fields(monitor::Report& r, const health::SupervisionReport& s) {
  using monitor::Field;
  switch (s.kind) {
    case health::SupervisionKind::Alive:
      r.add_field(Field::of_count("last_cycle", s.last_window_count));
      r.add_field(Field::of_count("this_cycle", s.window_count));
      break;
    case health::SupervisionKind::Deadline:
      if (s.evaluations > 0) {
        r.add_field(Field::of_duration("last", s.last_duration_ns));
        r.add_field(Field::of_duration("min", s.min_duration_ns));
        r.add_field(Field::of_duration("max", s.max_duration_ns));
      }
      break;
    case health::SupervisionKind::Logical:
      if (!s.current.empty()) r.add_field(Field::of_text("at", s.current));
      break;
  }
}

}  // namespace

monitor::Report supervision_unit(const health::SupervisionReport& s) {
  using monitor::Field;
  monitor::Report r;
  r.kind = monitor::ReportKind::Unit;
  r.unit_kind = std::string(kSupervisionUnit);
  r.name = "supervision " + s.name;
  r.state_label = health::to_string(s.status);
  const StatusLevel level = monitor::status_level(s.status);
  if (level != StatusLevel::Ok) {
    r.merge(level, s.has_failure ? s.last_failure.text : std::string(health::to_string(s.status)));
  }
  r.add_field(Field::of_text("type", health::to_string(s.kind)));
  std::string entities;
  for (const std::string& e : s.entities) entities += (entities.empty() ? "" : ", ") + e;
  r.add_field(Field::of_text("entities", std::move(entities)));
  r.depends_on = s.entities;  // the diagnosis graph: a failed component explains its supervision
  r.add_field(Field::of_count("checkpoints", s.checkpoints));
  r.add_field(Field::of_count("lost", s.lost));
  r.add_field(Field::of_count("evaluations", s.evaluations));
  r.add_field(Field::of_count("failures", s.failures));
  r.add_field(Field::of_count("failed", s.failed_count));
  r.add_field(Field::of_count("tolerance", s.tolerance));
  r.add_field(Field::of_count("expirations", s.expirations));
  add_kind_fields(r, s);
  if (s.has_failure) {
    r.add_field(Field::of_text("last_failure", health::to_string(s.last_failure.failure)));
    r.add_field(Field::of_duration("detected_after", s.last_failure.latency_ns()));
  }
  return r;
}

void HealthUnits::contribute(exporter::Snapshot& snapshot) {
  for (const health::SupervisionReport& s : aggregator_.health_reports()) {
    snapshot.reports.components.push_back(supervision_unit(s));
  }
}

}  // namespace vigil::service
