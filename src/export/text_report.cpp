#include "vigil/export/text_report.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "vigil/platform/process.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>

namespace vigil::exporter {

namespace {

const char* color_of(StatusLevel l) noexcept {
  switch (l) {
    case StatusLevel::Ok:
      return "\x1b[32m";  // green
    case StatusLevel::Warn:
      return "\x1b[33m";  // yellow
    case StatusLevel::Error:
      return "\x1b[1;31m";  // bold red
    case StatusLevel::Stale:
      return "\x1b[35m";  // magenta
  }
  return "";
}
constexpr const char* kReset = "\x1b[0m";

// Text from components (names, exception texts) made safe for one line of a terminal: control
// characters, ESC included, are shown escaped (\n, \x1b) instead of moving the cursor.
std::string printable(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7F) {
      out += fmt::format("\\x{:02x}", c);
    } else {
      out += ch;
    }
  }
  return out;
}

// The status word padded to `width`, coloured without counting the escapes in the width.
std::string status_word(StatusLevel l, bool color, std::size_t width) {
  const std::string_view word = to_string(l);
  std::string out;
  if (color) out += color_of(l);
  out += word;
  if (color) out += kReset;
  if (word.size() < width) out.append(width - word.size(), ' ');
  return out;
}

std::string state_of(const Report& r) {
  if (!r.state_label.empty()) return r.state_label;
  if (!r.alive) return "left";
  return to_string(r.state);
}

std::string stats_line(const StatsSummary& s) {
  if (s.count == 0) return "-";
  return fmt::format(
      "mean {}, ewma {}, min {}, max {}, p50 {}, p99 {}, p99.9 {} ({} samples)",
      format_nanos(s.mean), format_nanos(s.ewma), format_nanos(static_cast<double>(s.min)),
      format_nanos(static_cast<double>(s.max)), format_nanos(static_cast<double>(s.p50)),
      format_nanos(static_cast<double>(s.p99)), format_nanos(static_cast<double>(s.p999)), s.count);
}

std::string losses_line(const std::array<std::uint64_t, task::kLossCauses>& losses) {
  std::string out;
  for (int i = 0; i < task::kLossCauses; ++i) {
    if (!out.empty()) out += ", ";
    out += fmt::format("{} {}", platform::to_string(static_cast<platform::LossCause>(i)),
                       losses[static_cast<std::size_t>(i)]);
  }
  return out;
}

constexpr std::size_t kNameWidth = 24;
// "mean/p99/max" and "p99/max": a duration is at most 7 characters ("-5.00us", "1.50ms").
constexpr std::size_t kExecutionWidth = 23;
constexpr std::size_t kLatencyWidth = 15;

std::string nanos_of(Nanos v) { return format_nanos(static_cast<double>(v)); }

// A unit's field in a table cell: a count, a duration, a distribution as p50/p99/max, words.
std::string cell_of(const Field& f) {
  switch (f.type) {
    case Field::Type::Count:
      return std::to_string(f.count);
    case Field::Type::Duration:
      return nanos_of(f.duration_ns);
    case Field::Type::Distribution:
      if (f.distribution.count == 0) return "-";
      return nanos_of(f.distribution.p50) + "/" + nanos_of(f.distribution.p99) + "/" +
             nanos_of(f.distribution.max);
    case Field::Type::Text:
      return printable(f.text);
  }
  return "?";
}

// A field's column title: its name in capitals, words apart ("rx_gap" -> "RX GAP P50/P99/MAX").
std::string title_of(const Field& f) {
  std::string t;
  for (const char c : f.name) {
    t += c == '_' ? ' ' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  if (f.type == Field::Type::Distribution) t += " P50/P99/MAX";
  return t;
}

// The units of one kind as a table: status, name, state, a column per field name (in the order
// of first appearance), the messages. Columns are as wide as their widest cell.
// A report's messages, after the root causes that explain it (the diagnosis graph's).
std::string messages_of(const Report& r) {
  std::string out;
  if (!r.caused_by.empty()) out = fmt::format("caused by {}", fmt::join(r.caused_by, ", "));
  const std::string own = r.status.summary();
  if (!own.empty()) out += (out.empty() ? "" : ": ") + own;
  return out;
}

std::string format_unit_table(const std::vector<const Report*>& units, bool color) {
  std::vector<std::string> titles;  // by field name, in order of first appearance
  std::vector<std::string> names;
  for (const Report* u : units) {
    for (const Field& f : u->fields) {
      if (std::find(names.begin(), names.end(), f.name) != names.end()) continue;
      names.push_back(f.name);
      titles.push_back(title_of(f));
    }
  }
  std::size_t name_width = kNameWidth;
  std::size_t state_width = 14;
  for (const Report* u : units) {
    name_width = std::max(name_width, printable(u->name).size());
    state_width = std::max(state_width, state_of(*u).size());
  }
  std::vector<std::size_t> widths;
  for (std::size_t i = 0; i < names.size(); ++i) {
    std::size_t width = titles[i].size();
    for (const Report* u : units) {
      if (const Field* f = u->field(names[i])) width = std::max(width, cell_of(*f).size());
    }
    widths.push_back(width);
  }
  std::string out = fmt::format("{:<7} {:<{}} {:<{}}", "STATUS", units.front()->kind_name(),
                                name_width, "STATE", state_width);
  for (std::size_t i = 0; i < names.size(); ++i)
    out += fmt::format("  {:>{}}", titles[i], widths[i]);
  out += "  MESSAGES\n";
  for (const Report* u : units) {
    out += status_word(u->status.level(), color, 7);
    out += fmt::format(" {:<{}} {:<{}}", printable(u->name), name_width, state_of(*u), state_width);
    for (std::size_t i = 0; i < names.size(); ++i) {
      const Field* f = u->field(names[i]);
      out += fmt::format("  {:>{}}", f != nullptr ? cell_of(*f) : std::string("-"), widths[i]);
    }
    const std::string messages = messages_of(*u);
    if (!messages.empty()) out += "  " + printable(messages);
    out += '\n';
  }
  return out;
}

}  // namespace

bool use_color(ColorMode mode, std::FILE* out) {
  switch (mode) {
    case ColorMode::Always:
      return true;
    case ColorMode::Never:
      return false;
    case ColorMode::Auto:
      break;
  }
  if (!platform::is_terminal(out)) return false;
  // https://no-color.org: any non-empty NO_COLOR disables colours.
  const char* no_color = std::getenv("NO_COLOR");  // NOLINT(concurrency-mt-unsafe): read-only
  if (no_color != nullptr && no_color[0] != '\0') return false;
  const char* term = std::getenv("TERM");  // NOLINT(concurrency-mt-unsafe): read-only
  return term == nullptr || std::strcmp(term, "dumb") != 0;
}

std::string format_root_causes(const ReportSet& reports, bool color) {
  std::string out;
  for (const std::string& name : reports.root_causes) {
    const Report* r = reports.find(name);
    if (r == nullptr) continue;
    std::size_t dependents = 0;
    for (const Report& d : reports.components) {
      if (std::find(d.caused_by.begin(), d.caused_by.end(), name) != d.caused_by.end()) {
        ++dependents;
      }
    }
    out +=
        fmt::format("ROOT CAUSE {} {}", status_word(r->status.level(), color, 5), printable(name));
    if (dependents > 0) {
      out += fmt::format(" ({} dependent{})", dependents, dependents == 1 ? "" : "s");
    }
    const std::string messages = r->status.summary();
    if (!messages.empty()) out += ": " + printable(messages);
    out += '\n';
  }
  return out;
}

std::string format_summary_header() {
  return fmt::format("{:<7} {:<{}} {:<14} {:>10}  {:<{}} {:>{}} {:>8} {:>7}  {}", "STATUS", "NAME",
                     kNameWidth, "STATE", "CYCLES", "EXEC MEAN/P99/MAX", kExecutionWidth,
                     "LAT P99/MAX", kLatencyWidth, "OVERRUNS", "LOSSES", "MESSAGES");
}

std::string format_summary_line(const Report& r, bool color) {
  if (r.kind == ReportKind::Unit) {
    // A unit alone: its state and its fields by name.
    std::string line = status_word(r.status.level(), color, 7);
    line += fmt::format(" {:<{}} {:<14}", printable(r.name), kNameWidth, state_of(r));
    for (const Field& f : r.fields) line += fmt::format("  {} {}", printable(f.name), cell_of(f));
    const std::string messages = messages_of(r);
    if (!messages.empty()) line += "  " + printable(messages);
    return line;
  }
  // The max beside the p99: one long cycle among thousands puts the mean above the p99, and
  // the max says why (and it is the latency figure cyclictest users read).
  const std::string execution = r.execution_ns.count == 0 ? std::string("-")
                                                          : format_nanos(r.execution_ns.mean) +
                                                                "/" + nanos_of(r.execution_ns.p99) +
                                                                "/" + nanos_of(r.execution_ns.max);
  const std::string latency = r.latency_ns.count == 0
                                  ? std::string("-")
                                  : nanos_of(r.latency_ns.p99) + "/" + nanos_of(r.latency_ns.max);
  std::string line = status_word(r.status.level(), color, 7);
  line += fmt::format(" {:<{}} {:<14} {:>10}  {:<{}} {:>{}} {:>8} {:>7}", printable(r.name),
                      kNameWidth, state_of(r), r.counters.cycles, execution, kExecutionWidth,
                      latency, kLatencyWidth,
                      r.counters.overruns - std::min(r.counters.overruns, r.warmup.overruns),
                      r.counters.total_losses());
  const std::string messages = messages_of(r);
  if (!messages.empty()) {
    line += "  ";
    line += printable(messages);
  }
  return line;
}

std::string format_summary(const ReportSet& reports, bool color) {
  // The root causes first (what to act on), then the components, the supervisor and the monitor
  // in one table; then each kind of unit in a table of its own, with its own columns, in the
  // order the kinds first appear.
  std::string out = format_root_causes(reports, color);
  if (!out.empty()) out += '\n';
  out += format_summary_header();
  out += '\n';
  std::vector<std::string_view> kinds;
  for (const Report& r : reports.components) {
    if (r.kind == ReportKind::Unit) {
      if (std::find(kinds.begin(), kinds.end(), r.unit_kind) == kinds.end()) {
        kinds.push_back(r.unit_kind);
      }
      continue;
    }
    out += format_summary_line(r, color);
    out += '\n';
  }
  for (const std::string_view kind : kinds) {
    std::vector<const Report*> units;
    for (const Report& r : reports.components) {
      if (r.is_unit(kind)) units.push_back(&r);
    }
    out += '\n';
    out += format_unit_table(units, color);
  }
  return out;
}

std::string format_detail(const Report& r, bool color) {
  std::string out =
      fmt::format("{}: {}\n", printable(r.name), status_word(r.status.level(), color, 0));
  const auto line = [&](std::string_view key, const std::string& value) {
    out += fmt::format("  {}: {}\n", printable(key), printable(value));
  };
  const bool component = r.kind == ReportKind::Component;
  for (const auto& m : r.status.messages()) {
    line("message", fmt::format("[{}] {}", to_string(m.level), m.text));
  }
  line("kind", component ? fmt::format("component (id {})", r.id) : std::string(r.kind_name()));
  if (r.kind == ReportKind::Unit) {
    line("state", state_of(r));
    for (const Field& f : r.fields) {
      line(f.name, f.type == Field::Type::Distribution ? stats_line(f.distribution) : cell_of(f));
    }
    for (const auto& kv : r.values) line(kv.key, kv.value);
    return out;
  }
  line("state", state_of(r) + (r.configured ? "" : " (not configured)"));
  if (r.configured) {
    std::string where =
        fmt::format("{}, {}", r.activity.empty() ? "-" : r.activity, platform::to_string(r.policy));
    if (r.policy == SchedPolicy::Fifo) where += fmt::format(" {}", r.priority);
    if (r.requested_policy != r.policy) {
      where += fmt::format(" (asked {})", platform::to_string(r.requested_policy));
    }
    where += r.cpu >= 0 ? fmt::format(", cpu {}", r.cpu) : std::string(", any cpu");
    if (r.tid != 0) {
      where += fmt::format(", tid {}, {} task{} on the thread", r.tid, r.tasks_on_thread,
                           r.tasks_on_thread == 1 ? "" : "s");
    }
    line("activity", where);
    line("period", r.period_ns > 0 ? format_nanos(static_cast<double>(r.period_ns))
                                   : std::string("none (not periodic)"));
  }
  if (!component) {
    // The supervisor and the monitor: their cycles and the time each took.
    line("cycles", std::to_string(r.counters.cycles));
    line("cycle time", stats_line(r.total_ns));
  } else {
    line("cycles", fmt::format("{} ({} samples)", r.counters.cycles, r.samples));
    line("overruns", fmt::format("{} ({} cycles missed; {} overruns in the {} warm-up cycles)",
                                 r.counters.overruns, r.counters.missed_cycles, r.warmup.overruns,
                                 r.warmup_cycles));
    line("window",
         fmt::format("{}{}: {} cycles, {} overruns, {} missed, {} rt losses, {} exceptions, "
                     "{} dropped",
                     r.window.first ? "since start" : "last ",
                     r.window.first ? "" : format_nanos(static_cast<double>(r.window.duration_ns)),
                     r.window.cycles, r.window.overruns, r.window.missed_cycles,
                     r.window.total_losses(), r.window.exceptions, r.window.dropped));
    line("execution time", stats_line(r.execution_ns));
    line("total time", stats_line(r.total_ns));
    line("wake-up latency", stats_line(r.latency_ns));
    line("measured period", stats_line(r.measured_period_ns));
    line("overhead", r.overhead_ns.count == 0
                         ? std::string("-")
                         : fmt::format("mean {} ({:.2f}% of total time)",
                                       format_nanos(r.overhead_ns.mean), r.overhead_share * 100.0));
    line("rt losses",
         fmt::format("{} ({})", r.counters.total_losses(), losses_line(r.counters.losses)));
    if (r.has_exception) {
      line("exceptions", fmt::format("{}; last in {} at cycle {}: {}: {}", r.exception.count,
                                     to_string(r.exception.hook), r.exception.cycle,
                                     r.exception.type, r.exception.message));
    } else {
      line("exceptions", std::to_string(r.counters.exceptions));
    }
    line("dropped", fmt::format("{} (port high water {}/{})", r.counters.dropped, r.port_high_water,
                                r.port_capacity));
  }
  if (r.silence_ns >= 0) line("silence", format_nanos(static_cast<double>(r.silence_ns)));
  if (r.thread) {
    const platform::ThreadStats& t = *r.thread;
    line("thread",
         fmt::format("tid {} '{}', {} {}, last cpu {}, switches {} voluntary / {} involuntary, "
                     "faults {} minor / {} major, cpu time {} user / {} system",
                     t.tid, t.name, t.policy_known ? platform::to_string(t.policy) : "other",
                     t.priority, t.last_cpu, t.voluntary_switches, t.involuntary_switches,
                     t.minor_faults, t.major_faults,
                     format_nanos(static_cast<double>(t.user_time_ns)),
                     format_nanos(static_cast<double>(t.system_time_ns))));
  }
  for (const auto& kv : r.values) line(kv.key, kv.value);
  return out;
}

std::string format_details(const ReportSet& reports, bool color) {
  std::string out;
  for (const Report& r : reports.components) {
    if (!out.empty()) out += '\n';
    out += format_detail(r, color);
  }
  return out;
}

void print_summary(std::FILE* out, const ReportSet& reports, ColorMode mode) {
  const std::string s = format_summary(reports, use_color(mode, out));
  std::fwrite(s.data(), 1, s.size(), out);
  std::fflush(out);
}

void print_details(std::FILE* out, const ReportSet& reports, ColorMode mode) {
  const std::string s = format_details(reports, use_color(mode, out));
  std::fwrite(s.data(), 1, s.size(), out);
  std::fflush(out);
}

}  // namespace vigil::exporter
