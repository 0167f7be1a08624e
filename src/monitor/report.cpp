#include "vigil/monitor/report.hpp"

#include <fmt/format.h>

#include <cmath>

namespace vigil::monitor {

const std::string* Report::value(std::string_view key) const noexcept {
  for (const auto& kv : values) {
    if (kv.key == key) return &kv.value;
  }
  return nullptr;
}

const Field* Report::field(std::string_view field_name) const noexcept {
  for (const auto& f : fields) {
    if (f.name == field_name) return &f;
  }
  return nullptr;
}

const Report* ReportSet::find(std::string_view name) const noexcept {
  for (const auto& r : components) {
    if (r.name == name) return &r;
  }
  return nullptr;
}

StatusLevel ReportSet::worst() const noexcept {
  StatusLevel w = StatusLevel::Ok;
  for (const auto& r : components) w = vigil::worst(w, r.status.level());
  return w;
}

std::string format_nanos(double ns) {
  if (!std::isfinite(ns)) return "?";
  const char* sign = ns < 0 ? "-" : "";
  const double a = std::fabs(ns);
  struct Unit {
    double scale;
    const char* name;
  };
  static constexpr Unit kUnits[] = {{1e9, "s"}, {1e6, "ms"}, {1e3, "us"}};
  for (const Unit& u : kUnits) {
    // Pick the unit at the rounded value, so that 999.96 us prints as "1.00ms", not "1000us".
    const double v = a / u.scale;
    if (v >= 0.9995) {
      if (v < 9.995) return fmt::format("{}{:.2f}{}", sign, v, u.name);
      if (v < 99.95) return fmt::format("{}{:.1f}{}", sign, v, u.name);
      return fmt::format("{}{:.0f}{}", sign, v, u.name);
    }
  }
  return fmt::format("{}{:.0f}ns", sign, a);
}

std::string format_field(const Field& f) {
  switch (f.type) {
    case Field::Type::Count:
      return std::to_string(f.count);
    case Field::Type::Duration:
      return format_nanos(static_cast<double>(f.duration_ns));
    case Field::Type::Distribution: {
      const StatsSummary& d = f.distribution;
      if (d.count == 0) return "-";
      return fmt::format("p50 {}, p99 {}, max {} ({} samples)",
                         format_nanos(static_cast<double>(d.p50)),
                         format_nanos(static_cast<double>(d.p99)),
                         format_nanos(static_cast<double>(d.max)), d.count);
    }
    case Field::Type::Text:
      return f.text;
  }
  return "?";
}

void fill_report(Report& r, const supervisor::ComponentSnapshot& s) {
  r.kind = ReportKind::Component;
  r.id = s.id;
  r.name = s.name;
  r.alive = s.alive;
  r.configured = s.has_info;
  if (s.has_info) {
    r.activity = s.info.activity.str();
    r.requested_policy = s.info.requested_policy;
    r.policy = s.info.policy;
    r.realtime_refused = s.info.realtime_refused;
    r.priority = s.info.priority;
    r.cpu = s.info.cpu;
    r.tid = s.info.tid;
    r.period_ns = s.info.period_ns;
  }
  r.state = s.state;
  r.counters = s.counters;
  r.samples = s.samples;
  r.execution_ns = s.execution_ns;
  r.total_ns = s.total_ns;
  r.latency_ns = s.latency_ns;
  r.measured_period_ns = s.measured_period_ns;
  r.overhead_ns = s.overhead_ns;
  r.overhead_share = s.overhead_share();
  r.port_capacity = s.port_capacity;
  r.port_high_water = s.port_high_water;
  r.warmup_cycles = s.warmup_cycles;
  r.warmup = s.warmup_counters;
  r.latch = s.latch;
  r.deadline_ns = s.deadline_ns;
  r.deadline_misses = s.deadline_misses;
  r.events = s.events;
  r.has_exception = s.has_exception;
  if (s.has_exception) {
    r.exception.count = s.counters.exceptions;
    r.exception.type = s.last_exception_type;
    r.exception.message = s.last_exception.message.str();
    r.exception.hook = s.last_exception.hook;
    r.exception.cycle = s.last_exception.cycle;
  }
}

}  // namespace vigil::monitor
