#include "vigil/service/thread_units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <vector>

#include "vigil/export/output.hpp"

namespace vigil::service {

namespace {

using monitor::Field;
using monitor::Report;
using monitor::ReportKind;
using monitor::StatusLevel;

// How long a component may stay silent before its thread counts as stuck for it: its watchdog
// deadline, else 10 periods (at least 100 ms), else (aperiodic) never.
Nanos limit_of(const Report& r) {
  if (r.deadline_ns > 0) return r.deadline_ns;
  if (r.period_ns > 0) return std::max<Nanos>(10 * r.period_ns, 100 * kNanosPerMilli);
  return 0;
}

}  // namespace

void add_thread_units(monitor::ReportSet& reports) {
  std::map<int, std::vector<std::size_t>> by_tid;  // tid -> component reports on it
  for (std::size_t i = 0; i < reports.components.size(); ++i) {
    const Report& r = reports.components[i];
    if (r.kind != ReportKind::Component || !r.alive || r.tid == 0) continue;
    by_tid[r.tid].push_back(i);
  }
  std::vector<Report> units;
  for (const auto& [tid, members] : by_tid) {
    if (members.size() < 2) continue;
    const Report& first = reports.components[members.front()];
    Report u;
    u.kind = ReportKind::Unit;
    u.unit_kind = std::string(kThreadUnit);
    u.name = fmt::format("thread {} (tid {})", first.activity, tid);
    u.configured = true;
    u.tid = tid;
    u.activity = first.activity;
    u.policy = first.policy;
    u.priority = first.priority;
    u.cpu = first.cpu;
    bool all_silent = true;
    bool any_running = false;
    Nanos least_silence = INT64_MAX;
    const Report* last_to_cycle = nullptr;
    std::string names;
    for (const std::size_t i : members) {
      Report& c = reports.components[i];
      names += (names.empty() ? "" : ", ") + c.name;
      c.depends_on.push_back(u.name);
      if (c.state != TaskState::Running || c.silence_ns < 0) continue;
      any_running = true;
      const Nanos limit = limit_of(c);
      if (limit <= 0 || c.silence_ns <= limit) all_silent = false;
      if (c.silence_ns < least_silence) {
        least_silence = c.silence_ns;
        last_to_cycle = &c;
      }
    }
    const bool stuck = any_running && all_silent;
    u.state_label = stuck ? "stuck" : "running";
    if (stuck) {
      u.merge(StatusLevel::Error,
              fmt::format("stuck or starved: none of its {} components cycled for {} (the last "
                          "to end a cycle: {}; the next in its order is the likely culprit)",
                          members.size(), monitor::format_nanos(static_cast<double>(least_silence)),
                          last_to_cycle != nullptr ? last_to_cycle->name : "?"));
    }
    u.add_field(Field::of_count("components", members.size()));
    u.add_field(Field::of_text("members", std::move(names)));
    if (any_running) u.add_field(Field::of_duration("silence", least_silence));
    units.push_back(std::move(u));
  }
  for (Report& u : units) reports.components.push_back(std::move(u));
}

void ThreadUnits::contribute(exporter::Snapshot& snapshot) { add_thread_units(snapshot.reports); }

}  // namespace vigil::service
