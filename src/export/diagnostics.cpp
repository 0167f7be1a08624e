#include "vigil/export/diagnostics.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "vigil/can/can_monitor.hpp"
#include "vigil/export/json_writer.hpp"

namespace vigil::exporter {

namespace {

std::string nanos_text(Nanos ns) { return format_nanos(static_cast<double>(ns)); }

void kv(exporter::JsonWriter& w, std::string_view key, const std::string& value) {
  w.begin_object().field("key", key).field("value", value).end_object();
}

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

std::string to_diagnostics_json(const ReportSet& reports, std::int64_t wall_time_ns, int indent) {
  exporter::JsonWriter w(indent);
  w.begin_object();
  w.key("header").begin_object();
  std::int64_t sec = wall_time_ns / 1'000'000'000;
  std::int64_t nsec = wall_time_ns % 1'000'000'000;
  if (nsec < 0) {
    nsec += 1'000'000'000;
    --sec;
  }
  w.key("stamp").begin_object().field("sec", sec).field("nanosec", nsec).end_object();
  w.field("frame_id", "");
  w.end_object();
  w.key("status").begin_array();
  for (const Report& r : reports.components) {
    w.begin_object();
    w.field("level", static_cast<int>(r.status.level()));
    w.field("name", "vigil: " + r.name);
    std::string message = r.status.summary();
    if (!r.caused_by.empty()) {
      message = fmt::format("caused by {}{}{}", fmt::join(r.caused_by, ", "),
                            message.empty() ? "" : ": ", message);
    }
    w.field("message", message.empty() ? std::string(to_string(r.status.level())) : message);
    w.field("hardware_id", hardware_id(r));
    w.key("values").begin_array();
    kv(w, "kind", std::string(r.kind_name()));
    kv(w, "state", r.state_label.empty() ? std::string(to_string(r.state)) : r.state_label);
    if (r.kind == ReportKind::Component) {
      kv(w, "activity", r.activity);
      kv(w, "policy", fmt::format("{} {}", platform::to_string(r.policy), r.priority));
      kv(w, "period", r.period_ns > 0 ? nanos_text(r.period_ns) : std::string("-"));
      kv(w, "cycles", std::to_string(r.counters.cycles));
      kv(w, "overruns", std::to_string(r.counters.overruns));
      kv(w, "missed_cycles", std::to_string(r.counters.missed_cycles));
      kv(w, "rt_losses", std::to_string(r.counters.total_losses()));
      kv(w, "exceptions", std::to_string(r.counters.exceptions));
      kv(w, "dropped", std::to_string(r.counters.dropped));
      if (r.execution_ns.count > 0) {
        kv(w, "execution_p99", nanos_text(r.execution_ns.p99));
        kv(w, "execution_max", nanos_text(r.execution_ns.max));
      }
      if (r.latency_ns.count > 0) {
        kv(w, "latency_p99", nanos_text(r.latency_ns.p99));
        kv(w, "latency_max", nanos_text(r.latency_ns.max));
      }
      if (r.has_exception) {
        kv(w, "last_exception", fmt::format("{}: {}", r.exception.type, r.exception.message));
      }
    } else if (r.kind == ReportKind::Unit) {
      for (const Field& f : r.fields) kv(w, f.name, format_field(f));
    } else {
      kv(w, "cycles", std::to_string(r.counters.cycles));
    }
    for (const auto& v : r.values) kv(w, v.key, v.value);
    // The diagnosis graph: a root cause says so; a dependent names its roots.
    if (std::find(reports.root_causes.begin(), reports.root_causes.end(), r.name) !=
        reports.root_causes.end()) {
      kv(w, "root_cause", "true");
    }
    if (!r.caused_by.empty()) kv(w, "caused_by", fmt::format("{}", fmt::join(r.caused_by, ", ")));
    w.end_array();
    w.end_object();
  }
  w.end_array();
  // Not in diagnostic_msgs/DiagnosticArray: the root causes, named once.
  w.key("root_causes").begin_array();
  for (const std::string& name : reports.root_causes) w.value("vigil: " + name);
  w.end_array();
  w.end_object();
  return w.take();
}

}  // namespace vigil::exporter
