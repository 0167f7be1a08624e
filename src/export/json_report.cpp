#include "vigil/export/json_report.hpp"

#include <string>

#include "vigil/version.hpp"

namespace vigil::exporter {

void write_json(JsonWriter& w, const StatsSummary& s) {
  w.begin_object();
  w.field("count", s.count);
  w.field("last", s.last);
  w.field("min", s.min);
  w.field("mean", s.mean);
  w.field("ewma", s.ewma);
  w.field("max", s.max);
  w.field("p50", s.p50);
  w.field("p90", s.p90);
  w.field("p99", s.p99);
  w.field("p999", s.p999);
  w.end_object();
}

namespace {

void write_losses(JsonWriter& w, const std::array<std::uint64_t, task::kLossCauses>& losses) {
  w.begin_object();
  for (int i = 0; i < task::kLossCauses; ++i) {
    w.field(platform::to_string(static_cast<platform::LossCause>(i)),
            losses[static_cast<std::size_t>(i)]);
  }
  w.end_object();
}

void write_thread(JsonWriter& w, const platform::ThreadStats& t) {
  w.begin_object();
  w.field("tid", t.tid);
  w.field("name", t.name);
  w.key("policy");
  if (t.policy_known) {
    w.value(platform::to_string(t.policy));
  } else {
    w.null();
  }
  w.field("priority", t.priority);
  w.field("last_cpu", t.last_cpu);
  w.field("voluntary_switches", t.voluntary_switches);
  w.field("involuntary_switches", t.involuntary_switches);
  w.field("minor_faults", t.minor_faults);
  w.field("major_faults", t.major_faults);
  w.field("user_time_ns", t.user_time_ns);
  w.field("system_time_ns", t.system_time_ns);
  w.field("primary_time_ns", t.primary_time_ns);
  w.field("mode_switches", t.mode_switches);
  w.end_object();
}

void write_counters(JsonWriter& w, const Report& r) {
  w.begin_object();
  w.field("cycles", r.counters.cycles);
  w.field("samples", r.samples);
  w.field("overruns", r.counters.overruns);
  w.field("missed_cycles", r.counters.missed_cycles);
  w.field("rt_losses", r.counters.total_losses());
  w.key("rt_losses_by_cause");
  write_losses(w, r.counters.losses);
  w.field("exceptions", r.counters.exceptions);
  w.field("dropped", r.counters.dropped);
  w.end_object();
}

void write_window(JsonWriter& w, const monitor::Window& window) {
  w.begin_object();
  w.field("first", window.first);
  w.field("duration_ns", window.duration_ns);
  w.field("cycles", window.cycles);
  w.field("overruns", window.overruns);
  w.field("missed_cycles", window.missed_cycles);
  w.field("rt_losses", window.total_losses());
  w.key("rt_losses_by_cause");
  write_losses(w, window.losses);
  w.field("exceptions", window.exceptions);
  w.field("dropped", window.dropped);
  w.end_object();
}

void write_warmup(JsonWriter& w, const Report& r) {
  w.begin_object();
  w.field("cycles", r.warmup_cycles);
  w.field("overruns", r.warmup.overruns);
  w.field("missed_cycles", r.warmup.missed_cycles);
  w.field("rt_losses", r.warmup.total_losses());
  w.field("exceptions", r.warmup.exceptions);
  w.end_object();
}

// The latched fault; its fields are empty or 0 while none is latched.
void write_latch(JsonWriter& w, const supervisor::LatchedFault& latch) {
  w.begin_object();
  w.field("active", latch.active);
  w.field("first_kind", latch.active ? to_string(latch.first_kind) : "");
  w.field("first_detail", latch.active ? latch.first_detail : std::string());
  w.field("last_kind", latch.active ? to_string(latch.last_kind) : "");
  w.field("first_ns", latch.active ? latch.first_ns : 0);
  w.field("last_ns", latch.active ? latch.last_ns : 0);
  w.field("count", latch.active ? latch.count : 0);
  w.field("raised", latch.raised);
  w.field("cleared", latch.cleared);
  w.end_object();
}

void write_timing(JsonWriter& w, const Report& r) {
  w.begin_object();
  w.key("execution_ns");
  write_json(w, r.execution_ns);
  w.key("total_ns");
  write_json(w, r.total_ns);
  w.key("latency_ns");
  write_json(w, r.latency_ns);
  w.key("measured_period_ns");
  write_json(w, r.measured_period_ns);
  w.key("overhead_ns");
  write_json(w, r.overhead_ns);
  w.field("overhead_share", r.overhead_share);
  w.key("silence_ns");
  if (r.silence_ns >= 0) {
    w.value(r.silence_ns);
  } else {
    w.null();
  }
  w.end_object();
}

void write_exception(JsonWriter& w, const monitor::ExceptionInfo& e) {
  w.begin_object();
  w.field("count", e.count);
  w.field("type", e.type);
  w.field("message", e.message);
  w.field("hook", to_string(e.hook));
  w.field("cycle", e.cycle);
  w.end_object();
}

// The status, its messages and its findings (level and text).
void write_status(JsonWriter& w, const Report& r) {
  w.field("status", to_string(r.status.level()));
  w.key("messages").begin_array();
  for (const auto& m : r.status.messages()) w.value(m.text);
  w.end_array();
  w.key("findings").begin_array();
  for (const auto& m : r.status.messages()) {
    w.begin_object().field("level", to_string(m.level)).field("text", m.text).end_object();
  }
  w.end_array();
  // The diagnosis graph: what it needs, and the root causes that explain its status.
  w.key("depends_on").begin_array();
  for (const auto& d : r.depends_on) w.value(d);
  w.end_array();
  w.key("caused_by").begin_array();
  for (const auto& c : r.caused_by) w.value(c);
  w.end_array();
}

// Name, kind, status with its messages, identity and placement.
void write_identity(JsonWriter& w, const Report& r) {
  w.field("name", r.name);
  w.field("kind", r.kind_name());
  w.field("id", r.id);
  write_status(w, r);
  w.field("alive", r.alive);
  w.field("configured", r.configured);
  w.field("state", r.state_label.empty() ? std::string(to_string(r.state)) : r.state_label);
  w.field("activity", r.activity);
  w.field("policy", platform::to_string(r.policy));
  w.field("requested_policy", platform::to_string(r.requested_policy));
  w.field("realtime_refused", r.realtime_refused);
  w.field("priority", r.priority);
  w.field("cpu", r.cpu);
  w.field("tid", r.tid);
  w.field("tasks_on_thread", r.tasks_on_thread);
  w.field("period_ns", r.period_ns);
}

// The key/values added by checks.
void write_values(JsonWriter& w, const Report& r) {
  w.key("values").begin_array();
  for (const auto& kv : r.values) {
    w.begin_object().field("key", kv.key).field("value", kv.value).end_object();
  }
  w.end_array();
}

// A unit: its name, kind, status and state, and its fields under their names (durations with the
// "_ns" suffix, as everywhere in the schema).
void write_unit(JsonWriter& w, const Report& r) {
  w.begin_object();
  w.field("name", r.name);
  w.field("kind", r.kind_name());
  write_status(w, r);
  w.field("state", r.state_label);
  w.key("fields").begin_object();
  for (const Field& f : r.fields) {
    switch (f.type) {
      case Field::Type::Count:
        w.field(f.name, f.count);
        break;
      case Field::Type::Duration:
        w.field(f.name + "_ns", f.duration_ns);
        break;
      case Field::Type::Distribution:
        w.key(f.name + "_ns");
        write_json(w, f.distribution);
        break;
      case Field::Type::Text:
        w.field(f.name, f.text);
        break;
    }
  }
  w.end_object();
  write_values(w, r);
  w.end_object();
}

}  // namespace

void write_json(JsonWriter& w, const Report& r) {
  if (r.kind == ReportKind::Unit) {
    write_unit(w, r);
    return;
  }
  w.begin_object();
  write_identity(w, r);
  w.key("counters");
  write_counters(w, r);
  w.key("window");
  write_window(w, r.window);
  w.key("warmup");
  write_warmup(w, r);
  w.key("latch");
  write_latch(w, r.latch);
  w.field("events", r.events);
  w.field("deadline_ns", r.deadline_ns);
  w.field("deadline_misses", r.deadline_misses);
  w.key("timing");
  write_timing(w, r);
  w.key("port").begin_object();
  w.field("capacity", r.port_capacity);
  w.field("high_water", r.port_high_water);
  w.end_object();
  w.key("exception");
  if (r.has_exception) {
    write_exception(w, r.exception);
  } else {
    w.null();
  }
  w.key("thread");
  if (r.thread) {
    write_thread(w, *r.thread);
  } else {
    w.null();
  }
  write_values(w, r);
  w.end_object();
}

std::string to_json(const ReportSet& reports, const JsonOptions& options) {
  JsonWriter w(options.indent);
  w.begin_object();
  w.field("schema", kJsonSchemaVersion);
  w.field("generator", std::string("vigil ") + kVersion);
  w.field("cycle", reports.cycle);
  w.field("time_ns", reports.time_ns);
  w.field("status", to_string(reports.worst()));
  w.key("root_causes").begin_array();
  for (const std::string& name : reports.root_causes) w.value(name);
  w.end_array();
  w.key("components").begin_array();
  for (const Report& r : reports.components) write_json(w, r);
  w.end_array();
  w.end_object();
  std::string out = w.take();
  if (options.indent > 0) out += '\n';
  return out;
}

}  // namespace vigil::exporter
