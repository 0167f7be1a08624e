#include "vigil/export/diagnostics.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <limits>

#include "vigil/can/can_monitor.hpp"
#include "vigil/export/json_writer.hpp"

namespace vigil::exporter {

namespace {

std::string nanos_text(Nanos ns) { return format_nanos(static_cast<double>(ns)); }

}  // namespace

std::string hardware_id(const Report& r) {
  switch (r.kind) {
    case ReportKind::Component:
      if (r.tid == 0) return {};
      return r.cpu >= 0 ? fmt::format("tid {} cpu {}", r.tid, r.cpu)
                        : fmt::format("tid {} cpu any", r.tid);
    case ReportKind::Supervisor:
    case ReportKind::Monitor:
      return "vigil";
    case ReportKind::Unit:
      if (r.is_unit(can::kNodeUnit)) {
        // "can0/drive_5" -> "can0:drive_5"
        std::string id = r.name;
        if (const auto slash = id.find('/'); slash != std::string::npos) id[slash] = ':';
        return id;
      }
      if (r.is_unit(can::kGroupUnit)) {
        constexpr std::string_view kPrefix = "can group ";
        std::string_view g = r.name;
        if (g.starts_with(kPrefix)) g.remove_prefix(kPrefix.size());
        return "can:" + std::string(g);
      }
      return {};
  }
  return {};
}

DiagnosticStatusMessage to_diagnostic_status(const Report& r) {
  DiagnosticStatusMessage d;
  d.level = static_cast<std::uint8_t>(r.status.level());
  d.name = "vigil: " + r.name;
  d.message = r.status.summary();
  if (!r.caused_by.empty()) {  // the diagnosis graph: a dependent names its root causes first
    d.message = fmt::format("caused by {}{}{}", fmt::join(r.caused_by, ", "),
                            d.message.empty() ? "" : ": ", d.message);
  }
  if (d.message.empty()) d.message = to_string(r.status.level());
  d.hardware_id = hardware_id(r);
  auto& v = d.values;
  const auto kv = [&v](std::string_view key, std::string value) {
    v.push_back(DiagnosticKeyValue{std::string(key), std::move(value)});
  };
  kv("kind", std::string(r.kind_name()));
  kv("state", r.state_label.empty() ? std::string(to_string(r.state)) : r.state_label);
  if (r.kind == ReportKind::Component) {
    kv("activity", r.activity);
    kv("policy", fmt::format("{} {}", platform::to_string(r.policy), r.priority));
    kv("period", r.period_ns > 0 ? nanos_text(r.period_ns) : std::string("-"));
    kv("cycles", std::to_string(r.counters.cycles));
    kv("overruns", std::to_string(r.counters.overruns));
    kv("missed_cycles", std::to_string(r.counters.missed_cycles));
    kv("rt_losses", std::to_string(r.counters.total_losses()));
    kv("exceptions", std::to_string(r.counters.exceptions));
    kv("dropped", std::to_string(r.counters.dropped));
    if (r.execution_ns.count > 0) {
      kv("execution_p99", nanos_text(r.execution_ns.p99));
      kv("execution_max", nanos_text(r.execution_ns.max));
    }
    if (r.latency_ns.count > 0) {
      kv("latency_p99", nanos_text(r.latency_ns.p99));
      kv("latency_max", nanos_text(r.latency_ns.max));
    }
    if (r.has_exception) {
      kv("last_exception", fmt::format("{}: {}", r.exception.type, r.exception.message));
    }
  } else if (r.kind == ReportKind::Unit) {
    for (const Field& f : r.fields) kv(f.name, format_field(f));
  } else {
    kv("cycles", std::to_string(r.counters.cycles));
  }
  for (const auto& value : r.values) kv(value.key, value.value);
  if (!r.caused_by.empty()) kv("caused_by", fmt::format("{}", fmt::join(r.caused_by, ", ")));
  return d;
}

DiagnosticArrayMessage to_diagnostic_array(const ReportSet& reports, std::int64_t wall_time_ns) {
  DiagnosticArrayMessage a;
  std::int64_t sec = wall_time_ns / kNanosPerSecond;
  std::int64_t nsec = wall_time_ns % kNanosPerSecond;
  if (nsec < 0) {
    nsec += kNanosPerSecond;
    --sec;
  }
  sec = std::clamp<std::int64_t>(sec, std::numeric_limits<std::int32_t>::min(),
                                 std::numeric_limits<std::int32_t>::max());
  a.sec = static_cast<std::int32_t>(sec);
  a.nanosec = static_cast<std::uint32_t>(nsec);
  a.status.reserve(reports.components.size());
  for (const Report& r : reports.components) {
    a.status.push_back(to_diagnostic_status(r));
    // The diagnosis graph's root causes: marked, and named once.
    if (std::find(reports.root_causes.begin(), reports.root_causes.end(), r.name) !=
        reports.root_causes.end()) {
      a.status.back().values.push_back(DiagnosticKeyValue{"root_cause", "true"});
      a.root_causes.push_back(a.status.back().name);
    }
  }
  return a;
}

std::string to_diagnostics_json(const DiagnosticArrayMessage& m, int indent) {
  exporter::JsonWriter w(indent);
  w.begin_object();
  w.key("header").begin_object();
  w.key("stamp")
      .begin_object()
      .field("sec", static_cast<std::int64_t>(m.sec))
      .field("nanosec", static_cast<std::int64_t>(m.nanosec))
      .end_object();
  w.field("frame_id", m.frame_id);
  w.end_object();
  w.key("status").begin_array();
  for (const DiagnosticStatusMessage& d : m.status) {
    w.begin_object();
    w.field("level", static_cast<int>(d.level));
    w.field("name", d.name);
    w.field("message", d.message);
    w.field("hardware_id", d.hardware_id);
    w.key("values").begin_array();
    for (const DiagnosticKeyValue& v : d.values) {
      w.begin_object().field("key", v.key).field("value", v.value).end_object();
    }
    w.end_array();
    w.end_object();
  }
  w.end_array();
  // Not in diagnostic_msgs/DiagnosticArray: the root causes, named once.
  w.key("root_causes").begin_array();
  for (const std::string& name : m.root_causes) w.value(name);
  w.end_array();
  w.end_object();
  return w.take();
}

std::string to_diagnostics_json(const ReportSet& reports, std::int64_t wall_time_ns, int indent) {
  return to_diagnostics_json(to_diagnostic_array(reports, wall_time_ns), indent);
}

}  // namespace vigil::exporter
