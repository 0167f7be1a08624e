#include "vigil/export/prometheus.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <iterator>
#include <optional>
#include <span>
#include <vector>

#include "utf8.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/health/report.hpp"
#include "vigil/version.hpp"

namespace vigil::exporter {

namespace {

// --- text helpers ------------------------------------------------------------------------------

// Escapes `s` for a HELP line (`quote`: OpenMetrics also escapes '"').
void append_help(std::string& out, std::string_view s, bool quote) {
  for (char c : s) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '"' && quote) {
      out += "\\\"";
    } else {
      out += c;
    }
  }
}

double seconds(double ns) noexcept { return ns / 1e9; }
double seconds(Nanos ns) noexcept { return static_cast<double>(ns) / 1e9; }

// A value added by a check, read as an unsigned integer (the supervisor's and monitor's figures,
// CAN frame counts): empty when absent or not a number.
std::optional<std::uint64_t> value_u64(const Report& r, std::string_view key) {
  const std::string* v = r.value(key);
  if (v == nullptr) return std::nullopt;
  std::uint64_t n = 0;
  const auto [end, ec] = std::from_chars(v->data(), v->data() + v->size(), n);
  if (ec != std::errc{} || end != v->data() + v->size()) return std::nullopt;
  return n;
}

// --- the writer --------------------------------------------------------------------------------

enum class Type : std::uint8_t { Gauge, Counter, Histogram, Summary, Info };

struct Label {
  std::string_view name;
  std::string_view value;
};

class Writer {
 public:
  Writer(std::string& out, ExpositionFormat f)
      : out_(out), om_(f == ExpositionFormat::OpenMetrics) {}

  // HELP, TYPE (and UNIT) of family `name` (the sample name for gauges, counters with their
  // `_total`, info with its `_info`; the base name for histograms and summaries). Written with
  // the family's first sample: a family without samples (no CAN bus...) is left out.
  void family(std::string_view name, Type type, std::string_view help) {
    pending_.clear();
    std::string& h = pending_;  // the header waits for the first sample
    std::string_view meta = name;
    const char* type_name = "gauge";
    switch (type) {
      case Type::Gauge:
        break;
      case Type::Counter:
        type_name = "counter";
        if (om_) meta.remove_suffix(std::string_view("_total").size());
        break;
      case Type::Histogram:
        type_name = "histogram";
        break;
      case Type::Summary:
        type_name = "summary";
        break;
      case Type::Info:
        if (om_) {
          type_name = "info";
          meta.remove_suffix(std::string_view("_info").size());
        }
        break;
    }
    h += "# HELP ";
    h += meta;
    h += ' ';
    append_help(h, help, om_);
    h += "\n# TYPE ";
    h += meta;
    h += ' ';
    h += type_name;
    h += '\n';
    if (om_ && type != Type::Info && meta.ends_with("_seconds")) {
      h += "# UNIT ";
      h += meta;
      h += " seconds\n";
    }
  }

  // One sample: `name{labels} value`. `labels` are written in order, `extra` after them.
  void sample(std::string_view name, std::string_view component, std::initializer_list<Label> extra,
              double value) {
    head(name, component, extra);
    append_number(out_, value);
    out_ += '\n';
  }
  // `exemplar` (when not null and naming a cycle) is written in OpenMetrics only; the caller
  // gives one only on a counter's `_total` or a histogram's `_bucket` sample.
  void sample_u(std::string_view name, std::string_view component,
                std::initializer_list<Label> extra, std::uint64_t value,
                const CycleExemplar* exemplar = nullptr) {
    head(name, component, extra);
    fmt::format_to(std::back_inserter(out_), "{}", value);
    if (om_ && exemplar != nullptr && exemplar->cycle != 0) append_exemplar(*exemplar);
    out_ += '\n';
  }

  void end() {
    if (om_) out_ += "# EOF\n";
  }

 private:
  void head(std::string_view name, std::string_view component, std::initializer_list<Label> extra) {
    if (!pending_.empty()) {
      out_ += pending_;
      pending_.clear();
    }
    out_ += name;
    bool first = true;
    const auto label = [&](std::string_view n, std::string_view v) {
      out_ += first ? '{' : ',';
      first = false;
      out_ += n;
      out_ += "=\"";
      append_label_value(out_, v);
      out_ += '"';
    };
    if (!component.empty()) label("component", component);
    for (const Label& l : extra) label(l.name, l.value);
    if (!first) out_ += '}';
    out_ += ' ';
  }

  // ` # {cycle="N",trace="M"} value [timestamp]`. The label set is two names of 5 characters
  // and two 64-bit integers (at most 20 digits each): at most 50 code points, within
  // OpenMetrics' 128.
  void append_exemplar(const CycleExemplar& e) {
    fmt::format_to(std::back_inserter(out_), " # {{cycle=\"{}\"", e.cycle);
    if (e.trace != 0) fmt::format_to(std::back_inserter(out_), ",trace=\"{}\"", e.trace);
    out_ += "} ";
    append_number(out_, e.value);
    if (e.unix_ns > 0) {
      // Milliseconds: what Prometheus keeps.
      const std::int64_t ms = e.unix_ns / 1'000'000;
      fmt::format_to(std::back_inserter(out_), " {}.{:03}", ms / 1000, ms % 1000);
    }
  }

  std::string& out_;
  bool om_;
  std::string pending_;
};

// le values of the fixed boundaries, in seconds, formatted once.
const std::array<std::string, kBucketBounds>& le_labels() {
  static const std::array<std::string, kBucketBounds> labels = [] {
    std::array<std::string, kBucketBounds> a;
    for (std::size_t i = 0; i < kBucketBounds; ++i) {
      append_number(a[i], static_cast<double>(kBucketBoundsNs[i]) / 1e9);
    }
    return a;
  }();
  return labels;
}

// The exemplars of one histogram: `exemplars` (sorted by histogram, bucket) narrowed to those of
// `histogram`; `at(i)` is bucket i's, or null.
class HistogramExemplars {
 public:
  HistogramExemplars() = default;
  HistogramExemplars(std::span<const BucketExemplar> exemplars, TimingHistogram histogram) {
    const auto first =
        std::find_if(exemplars.begin(), exemplars.end(),
                     [&](const BucketExemplar& b) { return b.histogram == histogram; });
    const auto last = std::find_if(
        first, exemplars.end(), [&](const BucketExemplar& b) { return b.histogram != histogram; });
    of_ = exemplars.subspan(static_cast<std::size_t>(first - exemplars.begin()),
                            static_cast<std::size_t>(last - first));
  }
  [[nodiscard]] const CycleExemplar* at(std::size_t bucket) {
    while (next_ < of_.size() && of_[next_].bucket < bucket) ++next_;
    return next_ < of_.size() && of_[next_].bucket == bucket ? &of_[next_].exemplar : nullptr;
  }

 private:
  std::span<const BucketExemplar> of_;
  std::size_t next_ = 0;  // buckets are asked for in order
};

void histogram_samples(Writer& w, std::string_view base, std::string_view component,
                       const BucketCounts* buckets, const StatsSummary& stats,
                       HistogramExemplars exemplars = {}) {
  const std::string bucket = std::string(base) + "_bucket";
  std::uint64_t count = stats.count;
  double sum_ns = stats.mean * static_cast<double>(stats.count);
  if (buckets != nullptr) {
    const auto& le = le_labels();
    for (std::size_t i = 0; i < kBucketBounds; ++i) {
      w.sample_u(bucket, component, {{"le", le[i]}}, buckets->cumulative[i], exemplars.at(i));
    }
    count = buckets->count;
    sum_ns = buckets->sum_ns;
  }
  w.sample_u(bucket, component, {{"le", "+Inf"}}, count,
             buckets != nullptr ? exemplars.at(kBucketBounds) : nullptr);
  w.sample(std::string(base) + "_sum", component, {}, seconds(sum_ns));
  w.sample_u(std::string(base) + "_count", component, {}, count);
}

// A histogram series with a `direction` label (CAN gaps): buckets when known, else count and sum
// alone.
void direction_histogram_samples(Writer& w, std::string_view base, std::string_view component,
                                 std::string_view direction, const BucketCounts* buckets,
                                 std::uint64_t count, double sum_ns) {
  const std::string bucket = std::string(base) + "_bucket";
  if (buckets != nullptr) {
    const auto& le = le_labels();
    for (std::size_t i = 0; i < kBucketBounds; ++i) {
      w.sample_u(bucket, component, {{"direction", direction}, {"le", le[i]}},
                 buckets->cumulative[i]);
    }
    count = buckets->count;
    sum_ns = buckets->sum_ns;
  }
  w.sample_u(bucket, component, {{"direction", direction}, {"le", "+Inf"}}, count);
  w.sample(std::string(base) + "_sum", component, {{"direction", direction}}, seconds(sum_ns));
  w.sample_u(std::string(base) + "_count", component, {{"direction", direction}}, count);
}

void summary_samples(Writer& w, std::string_view base, std::string_view component,
                     const StatsSummary& s) {
  const std::string_view b = base;
  if (s.count > 0) {
    w.sample(b, component, {{"quantile", "0.5"}}, seconds(s.p50));
    w.sample(b, component, {{"quantile", "0.9"}}, seconds(s.p90));
    w.sample(b, component, {{"quantile", "0.99"}}, seconds(s.p99));
    w.sample(b, component, {{"quantile", "0.999"}}, seconds(s.p999));
  }
  w.sample(std::string(base) + "_sum", component, {},
           seconds(s.mean * static_cast<double>(s.count)));
  w.sample_u(std::string(base) + "_count", component, {}, s.count);
}

constexpr std::array<TaskState, 5> kStates = {TaskState::PreOperational, TaskState::Stopped,
                                              TaskState::Running, TaskState::Exception,
                                              TaskState::FatalError};

}  // namespace

// --- public helpers ----------------------------------------------------------------------------

ExpositionFormat negotiate_format(std::string_view accept) noexcept {
  // Accept: application/openmetrics-text;version=1.0.0;q=0.5,text/plain;version=0.0.4;q=0.4,...
  std::size_t pos = 0;
  while (pos <= accept.size()) {
    std::size_t end = accept.find(',', pos);
    if (end == std::string_view::npos) end = accept.size();
    std::string_view item = accept.substr(pos, end - pos);
    while (!item.empty() && (item.front() == ' ' || item.front() == '\t')) item.remove_prefix(1);
    if (item.starts_with("application/openmetrics-text")) {
      // A q-value of 0 means "not acceptable".
      const std::size_t q = item.find("q=");
      if (q == std::string_view::npos) return ExpositionFormat::OpenMetrics;
      std::string_view qv = item.substr(q + 2);
      const std::size_t stop = qv.find(';');
      if (stop != std::string_view::npos) qv = qv.substr(0, stop);
      double value = 0;
      const auto [p, ec] = std::from_chars(qv.data(), qv.data() + qv.size(), value);
      (void)p;
      if (ec != std::errc{} || value > 0) return ExpositionFormat::OpenMetrics;
    }
    pos = end + 1;
  }
  return ExpositionFormat::Prometheus;
}

const char* content_type(ExpositionFormat format) noexcept {
  return format == ExpositionFormat::OpenMetrics
             ? "application/openmetrics-text; version=1.0.0; charset=utf-8"
             : "text/plain; version=0.0.4; charset=utf-8";
}

void append_label_value(std::string& out, std::string_view value) {
  // Fast path: plain ASCII without anything to escape (nearly every name).
  bool plain = true;
  for (char c : value) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x80 || c == '\\' || c == '"' || c == '\n') {
      plain = false;
      break;
    }
  }
  if (plain) {
    out.append(value);
    return;
  }
  std::size_t i = 0;
  while (i < value.size()) {
    const char c = value[i];
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else if (static_cast<unsigned char>(c) < 0x80) {
      out += c;
    } else {
      unsigned code = 0;
      const std::size_t n = detail::utf8_sequence(value, i, code);
      if (n == 0) {
        out += "\xEF\xBF\xBD";  // U+FFFD
        ++i;
        continue;
      }
      out.append(value.substr(i, n));
      i += n;
      continue;
    }
    ++i;
  }
}

void append_number(std::string& out, double v) {
  if (std::isnan(v)) {
    out += "NaN";
  } else if (std::isinf(v)) {
    out += v > 0 ? "+Inf" : "-Inf";
  } else if (v == std::floor(v) && std::fabs(v) < 9.007199254740992e15) {
    fmt::format_to(std::back_inserter(out), "{}", static_cast<std::int64_t>(v));
  } else {
    fmt::format_to(std::back_inserter(out), "{}", v);
  }
}

std::string render_metrics(const MetricsSnapshot& snapshot, ExpositionFormat format) {
  std::string out;
  render_metrics(out, snapshot, format);
  return out;
}

namespace {

// --- the sections: one writer per group of families, in the order they are exposed ------------

bool any_report(const Report&) { return true; }
bool is_component(const Report& r) { return r.kind == ReportKind::Component; }
bool has_thread(const Report& r) { return r.thread.has_value(); }
bool is_supervisor(const Report& r) { return r.kind == ReportKind::Supervisor; }
bool is_monitor(const Report& r) { return r.kind == ReportKind::Monitor; }
bool is_can_node(const Report& r) { return r.is_unit(can::kNodeUnit); }
bool is_can_group(const Report& r) { return r.is_unit(can::kGroupUnit); }
bool is_can_bus(const Report& r) { return r.is_unit(can::kBusUnit); }
bool is_supervision(const Report& r) { return r.is_unit(health::kSupervisionUnit); }
bool is_reactions(const Report& r) { return r.is_unit("reactions"); }

// A unit's count field, if it has it.
std::optional<std::uint64_t> count_field(const Report& r, std::string_view name) {
  const Field* f = r.field(name);
  if (f == nullptr || f->type != Field::Type::Count) return std::nullopt;
  return f->count;
}
// A unit's duration field, if it has it.
std::optional<Nanos> duration_field(const Report& r, std::string_view name) {
  const Field* f = r.field(name);
  if (f == nullptr || f->type != Field::Type::Duration) return std::nullopt;
  return f->duration_ns;
}
// A unit's distribution field; an empty one when it has none.
const StatsSummary& distribution_field(const Report& r, std::string_view name) {
  static const StatsSummary kNone{};
  const Field* f = r.field(name);
  return f != nullptr && f->type == Field::Type::Distribution ? f->distribution : kNone;
}

// What a section writer reads and writes.
struct Section {
  Writer& w;
  const MetricsSnapshot& snap;

  // `fn(r)` for each report `r` that `pred` accepts, in the snapshot's order.
  template <class Pred, class Fn>
  void each(Pred pred, Fn fn) const {
    for (const Report& r : snap.reports.components) {
      if (pred(r)) fn(r);
    }
  }
};

void process_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_build_info", Type::Info, "vigil's version (value 1).");
  w.sample("vigil_build_info", {}, {{"version", kVersion}}, 1);
  w.family("vigil_report_timestamp_seconds", Type::Gauge,
           "Unix time at which the monitor published the reports served.");
  w.sample("vigil_report_timestamp_seconds", {}, {},
           static_cast<double>(s.snap.wall_time_ns) / 1e9);
  w.family("vigil_reports", Type::Gauge,
           "Reports served, by kind of report (the monitor's kinds, then each kind of unit).");
  // The monitor's kinds always (0 included), then the units' kinds in order of appearance.
  std::vector<std::pair<std::string_view, std::uint64_t>> n{{to_string(ReportKind::Component), 0},
                                                            {to_string(ReportKind::Supervisor), 0},
                                                            {to_string(ReportKind::Monitor), 0}};
  for (const Report& r : s.snap.reports.components) {
    const std::string_view kind = r.kind_name();
    auto it = std::find_if(n.begin(), n.end(), [&](const auto& e) { return e.first == kind; });
    if (it == n.end()) it = n.insert(n.end(), {kind, 0});
    ++it->second;
  }
  for (const auto& [kind, count] : n) w.sample_u("vigil_reports", {}, {{"kind", kind}}, count);
}

// Every report: status and state.
void status_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_component_status", Type::Gauge,
           "Status of a component (or of the supervisor, monitor, CAN node or group): "
           "0 OK, 1 WARN, 2 ERROR, 3 STALE.");
  s.each(any_report, [&](const Report& r) {
    w.sample_u("vigil_component_status", r.name, {{"kind", r.kind_name()}},
               static_cast<std::uint64_t>(r.status.level()));
  });
  w.family("vigil_component_state", Type::Gauge,
           "Lifecycle state: 1 for the current one. Components have one series per state; CAN "
           "nodes and groups one for their state in words.");
  s.each(any_report, [&](const Report& r) {
    const std::string_view kind = r.kind_name();
    if (!r.state_label.empty()) {
      w.sample_u("vigil_component_state", r.name, {{"kind", kind}, {"state", r.state_label}}, 1);
      return;
    }
    for (TaskState st : kStates) {
      w.sample_u("vigil_component_state", r.name, {{"kind", kind}, {"state", to_string(st)}},
                 r.state == st ? 1 : 0);
    }
  });
}

// The diagnosis graph: the root causes, and what each dependent report's status comes from.
void diagnosis_families(const Section& s) {
  Writer& w = s.w;
  const ReportSet& reports = s.snap.reports;
  w.family("vigil_root_cause", Type::Gauge,
           "1 for each report whose status (not OK) no failed dependency explains: what to act on "
           "first (the diagnosis graph).");
  for (const std::string& name : reports.root_causes) {
    const Report* r = reports.find(name);
    if (r == nullptr) continue;
    w.sample_u("vigil_root_cause", name, {{"kind", r->kind_name()}}, 1);
  }
  w.family("vigil_caused_by", Type::Gauge,
           "1 for each root cause (label cause) that explains a dependent report's status.");
  s.each(any_report, [&](const Report& r) {
    for (const std::string& cause : r.caused_by) {
      w.sample_u("vigil_caused_by", r.name, {{"cause", cause}}, 1);
    }
  });
}

void component_placement_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_component_info", Type::Info,
           "Placement of a component (value 1): activity, scheduling policy and priority, CPU.");
  s.each(is_component, [&](const Report& r) {
    const std::string prio = std::to_string(r.priority);
    const std::string cpu = std::to_string(r.cpu);
    w.sample("vigil_component_info", r.name,
             {{"activity", r.activity},
              {"policy", platform::to_string(r.policy)},
              {"requested_policy", platform::to_string(r.requested_policy)},
              {"priority", prio},
              {"cpu", cpu}},
             1);
  });
  w.family("vigil_component_alive", Type::Gauge,
           "1 while the component is registered, 0 once it left (reported for a while).");
  s.each(is_component,
         [&](const Report& r) { w.sample_u("vigil_component_alive", r.name, {}, r.alive); });
  w.family("vigil_component_realtime_refused", Type::Gauge,
           "1 when SCHED_FIFO was asked for but refused, and the component runs SCHED_OTHER.");
  s.each(is_component, [&](const Report& r) {
    w.sample_u("vigil_component_realtime_refused", r.name, {}, r.realtime_refused);
  });
  w.family("vigil_component_period_seconds", Type::Gauge,
           "Configured period of the component; 0 when not periodic.");
  s.each(is_component, [&](const Report& r) {
    w.sample("vigil_component_period_seconds", r.name, {}, seconds(r.period_ns));
  });
  w.family("vigil_component_tasks_on_thread", Type::Gauge,
           "Alive components that share the component's thread, itself included.");
  s.each(is_component, [&](const Report& r) {
    w.sample_u("vigil_component_tasks_on_thread", r.name, {}, r.tasks_on_thread);
  });
}

// A counter family with one sample per component: `get(report)`.
template <class Get>
void component_counter(const Section& s, std::string_view name, std::string_view help, Get get) {
  s.w.family(name, Type::Counter, help);
  s.each(is_component, [&](const Report& r) { s.w.sample_u(name, r.name, {}, get(r)); });
}

void component_counter_families(const Section& s) {
  component_counter(s, "vigil_component_cycles_total",
                    "Cycles run (exact, even when samples were dropped).",
                    [](const Report& r) { return r.counters.cycles; });
  component_counter(
      s, "vigil_component_samples_total",
      "Cycle samples the supervisor received (fewer than cycles when the port dropped some).",
      [](const Report& r) { return r.samples; });
  s.w.family("vigil_component_overruns_total", Type::Counter,
             "Cycles that ended after the next release.");
  s.each(is_component, [&](const Report& r) {
    const ComponentHistograms* h = s.snap.histograms_of(r);
    s.w.sample_u("vigil_component_overruns_total", r.name, {}, r.counters.overruns,
                 h != nullptr ? &h->overrun : nullptr);
  });
  component_counter(s, "vigil_component_missed_cycles_total",
                    "Releases skipped or run late because of overruns.",
                    [](const Report& r) { return r.counters.missed_cycles; });
  s.w.family("vigil_component_rt_losses_total", Type::Counter,
             "Real-time losses detected in the component's update, by cause.");
  s.each(is_component, [&](const Report& r) {
    for (int i = 0; i < task::kLossCauses; ++i) {
      s.w.sample_u("vigil_component_rt_losses_total", r.name,
                   {{"cause", platform::to_string(static_cast<platform::LossCause>(i))}},
                   r.counters.losses[static_cast<std::size_t>(i)]);
    }
  });
  component_counter(s, "vigil_component_exceptions_total",
                    "Exceptions thrown by the component's hooks.",
                    [](const Report& r) { return r.counters.exceptions; });
  component_counter(
      s, "vigil_component_dropped_messages_total",
      "Messages the component's port dropped because it was full (timing detail only).",
      [](const Report& r) { return r.counters.dropped; });
}

// A histogram family with one series per component: the buckets `pick_buckets(histograms)` when
// the snapshot has them, else the count and sum of `pick_stats(report)`.
template <class PickBuckets, class PickStats>
void component_histogram(const Section& s, std::string_view base, std::string_view help,
                         TimingHistogram which, PickBuckets pick_buckets, PickStats pick_stats) {
  s.w.family(base, Type::Histogram, help);
  s.each(is_component, [&](const Report& r) {
    const ComponentHistograms* h = s.snap.histograms_of(r);
    histogram_samples(
        s.w, base, r.name, h != nullptr ? &pick_buckets(*h) : nullptr, pick_stats(r),
        h != nullptr ? HistogramExemplars(h->exemplars, which) : HistogramExemplars());
  });
}

void component_histogram_families(const Section& s) {
  component_histogram(
      s, "vigil_component_execution_seconds",
      "Time spent in the component's on_update(), per cycle.", TimingHistogram::Execution,
      [](const ComponentHistograms& h) -> const BucketCounts& { return h.execution; },
      [](const Report& r) -> const StatsSummary& { return r.execution_ns; });
  component_histogram(
      s, "vigil_component_total_seconds",
      "Time per cycle including supervision (on_update() plus the latest measured overhead).",
      TimingHistogram::Total,
      [](const ComponentHistograms& h) -> const BucketCounts& { return h.total; },
      [](const Report& r) -> const StatsSummary& { return r.total_ns; });
  component_histogram(
      s, "vigil_component_wakeup_latency_seconds",
      "Wake-up latency: start of a cycle minus its scheduled release.", TimingHistogram::Latency,
      [](const ComponentHistograms& h) -> const BucketCounts& { return h.latency; },
      [](const Report& r) -> const StatsSummary& { return r.latency_ns; });
  component_histogram(
      s, "vigil_component_measured_period_seconds",
      "Measured period: start-to-start time of consecutive cycles.",
      TimingHistogram::MeasuredPeriod,
      [](const ComponentHistograms& h) -> const BucketCounts& { return h.measured_period; },
      [](const Report& r) -> const StatsSummary& { return r.measured_period_ns; });
}

// Supervision's share, silence and port of each component.
void component_gauge_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_component_overhead_ratio", Type::Gauge,
           "Supervision's share of the component's cycle time (mean overhead / mean total).");
  s.each(is_component, [&](const Report& r) {
    w.sample("vigil_component_overhead_ratio", r.name, {}, r.overhead_share);
  });
  w.family("vigil_component_silence_seconds", Type::Gauge,
           "Time since the latest cycle of a running component arrived (absent when not running).");
  s.each([](const Report& r) { return r.kind == ReportKind::Component && r.silence_ns >= 0; },
         [&](const Report& r) {
           w.sample("vigil_component_silence_seconds", r.name, {}, seconds(r.silence_ns));
         });
  w.family("vigil_component_port_capacity", Type::Gauge,
           "Capacity of the component's message port, in messages.");
  s.each(is_component, [&](const Report& r) {
    w.sample_u("vigil_component_port_capacity", r.name, {}, r.port_capacity);
  });
  w.family("vigil_component_port_high_water", Type::Gauge,
           "Highest occupancy of the component's port seen at a drain, in messages.");
  s.each(is_component, [&](const Report& r) {
    w.sample_u("vigil_component_port_high_water", r.name, {}, r.port_high_water);
  });
}

// A counter family with one sample per known thread: `get(thread stats)`.
template <class Get>
void thread_counter(const Section& s, std::string_view name, std::string_view help, Get get) {
  s.w.family(name, Type::Counter, help);
  s.each(has_thread, [&](const Report& r) { s.w.sample_u(name, r.name, {}, get(*r.thread)); });
}

// The threads' OS counters (components and the monitor).
void thread_families(const Section& s) {
  Writer& w = s.w;
  thread_counter(s, "vigil_thread_voluntary_switches_total",
                 "Voluntary context switches of the component's thread (it blocked).",
                 [](const platform::ThreadStats& t) { return t.voluntary_switches; });
  thread_counter(s, "vigil_thread_involuntary_switches_total",
                 "Involuntary context switches of the component's thread (it was preempted).",
                 [](const platform::ThreadStats& t) { return t.involuntary_switches; });
  thread_counter(s, "vigil_thread_minor_faults_total",
                 "Minor page faults of the component's thread.",
                 [](const platform::ThreadStats& t) { return t.minor_faults; });
  thread_counter(s, "vigil_thread_major_faults_total",
                 "Major page faults of the component's thread.",
                 [](const platform::ThreadStats& t) { return t.major_faults; });
  w.family("vigil_thread_cpu_seconds_total", Type::Counter,
           "CPU time of the component's thread by mode (kernel tick resolution).");
  s.each(has_thread, [&](const Report& r) {
    w.sample("vigil_thread_cpu_seconds_total", r.name, {{"mode", "user"}},
             seconds(r.thread->user_time_ns));
    w.sample("vigil_thread_cpu_seconds_total", r.name, {{"mode", "system"}},
             seconds(r.thread->system_time_ns));
  });
  w.family("vigil_thread_primary_seconds_total", Type::Counter,
           "Xenomai Cobalt: time of the thread in primary mode (0 on Linux).");
  s.each(has_thread, [&](const Report& r) {
    w.sample("vigil_thread_primary_seconds_total", r.name, {}, seconds(r.thread->primary_time_ns));
  });
  thread_counter(s, "vigil_thread_mode_switches_total",
                 "Xenomai Cobalt: switches of the thread to secondary mode (0 on Linux).",
                 [](const platform::ThreadStats& t) { return t.mode_switches; });
  w.family("vigil_thread_last_cpu", Type::Gauge, "CPU the component's thread last ran on.");
  s.each(has_thread, [&](const Report& r) {
    w.sample("vigil_thread_last_cpu", r.name, {}, static_cast<double>(r.thread->last_cpu));
  });
}

void supervisor_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_supervisor_cycles_total", Type::Counter, "Drain cycles of the supervisor.");
  s.each(is_supervisor, [&](const Report& r) {
    w.sample_u("vigil_supervisor_cycles_total", r.name, {}, r.counters.cycles);
  });
  w.family("vigil_supervisor_messages_total", Type::Counter,
           "Messages the supervisor drained from the components' ports.");
  s.each(is_supervisor, [&](const Report& r) {
    if (auto n = value_u64(r, "messages"))
      w.sample_u("vigil_supervisor_messages_total", r.name, {}, *n);
  });
  w.family("vigil_supervisor_ports", Type::Gauge, "Ports the supervisor drains.");
  s.each(is_supervisor, [&](const Report& r) {
    if (auto n = value_u64(r, "ports")) w.sample_u("vigil_supervisor_ports", r.name, {}, *n);
  });
  w.family("vigil_supervisor_port_high_water", Type::Gauge,
           "Highest port occupancy the supervisor saw at a drain, in messages.");
  s.each(is_supervisor, [&](const Report& r) {
    w.sample_u("vigil_supervisor_port_high_water", r.name, {}, r.port_high_water);
  });
  w.family("vigil_supervisor_period_seconds", Type::Gauge, "Period of the supervisor's thread.");
  s.each(is_supervisor, [&](const Report& r) {
    w.sample("vigil_supervisor_period_seconds", r.name, {}, seconds(r.period_ns));
  });
  w.family("vigil_supervisor_drain_seconds", Type::Summary,
           "Time of one supervisor cycle (draining every port).");
  s.each(is_supervisor, [&](const Report& r) {
    summary_samples(w, "vigil_supervisor_drain_seconds", r.name, r.total_ns);
  });
}

void monitor_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_monitor_cycles_total", Type::Counter, "Cycles of the monitor.");
  s.each(is_monitor, [&](const Report& r) {
    w.sample_u("vigil_monitor_cycles_total", r.name, {}, r.counters.cycles);
  });
  w.family("vigil_monitor_period_seconds", Type::Gauge, "Period of the monitor's thread.");
  s.each(is_monitor, [&](const Report& r) {
    w.sample("vigil_monitor_period_seconds", r.name, {}, seconds(r.period_ns));
  });
  w.family("vigil_monitor_cycle_seconds", Type::Summary,
           "Time of one monitor cycle (checks on every component).");
  s.each(is_monitor, [&](const Report& r) {
    summary_samples(w, "vigil_monitor_cycle_seconds", r.name, r.total_ns);
  });
  w.family("vigil_monitor_components", Type::Gauge, "Components the monitor checked.");
  s.each(is_monitor, [&](const Report& r) {
    if (auto n = value_u64(r, "components")) w.sample_u("vigil_monitor_components", r.name, {}, *n);
  });
  w.family("vigil_monitor_checks", Type::Gauge, "Checks the monitor runs on every component.");
  s.each(is_monitor, [&](const Report& r) {
    if (auto n = value_u64(r, "checks")) w.sample_u("vigil_monitor_checks", r.name, {}, *n);
  });
  w.family("vigil_monitor_thresholds_generation", Type::Gauge,
           "Generation of the watched threshold file (0 when none is watched).");
  s.each(is_monitor, [&](const Report& r) {
    if (auto n = value_u64(r, "thresholds_generation")) {
      w.sample_u("vigil_monitor_thresholds_generation", r.name, {}, *n);
    }
  });
}

void can_node_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_can_frames_total", Type::Counter,
           "CAN frames of a node by direction: rx (from the node), tx (to the node).");
  s.each(is_can_node, [&](const Report& r) {
    const auto rx = count_field(r, "frames_rx");
    const auto tx = count_field(r, "frames_tx");
    if (rx) w.sample_u("vigil_can_frames_total", r.name, {{"direction", "rx"}}, *rx);
    if (tx) w.sample_u("vigil_can_frames_total", r.name, {{"direction", "tx"}}, *tx);
  });
  w.family("vigil_can_gap_seconds", Type::Histogram,
           "Time between consecutive frames of a CAN node by direction: rx (from the node), tx "
           "(to the node).");
  s.each(is_can_node, [&](const Report& r) {
    const CanHistograms* h = s.snap.can_histograms_of(r);
    // Without buckets (a publisher that collected none): the count and sum of the report's
    // receive gaps.
    const StatsSummary& rx = distribution_field(r, "rx_gap");
    direction_histogram_samples(w, "vigil_can_gap_seconds", r.name, "rx",
                                h != nullptr && h->rx_gap ? &*h->rx_gap : nullptr, rx.count,
                                rx.mean * static_cast<double>(rx.count));
    if (h != nullptr && h->tx_gap) {
      direction_histogram_samples(w, "vigil_can_gap_seconds", r.name, "tx", &*h->tx_gap, 0, 0.0);
    }
  });
  w.family("vigil_can_read_seconds", Type::Summary,
           "Time of the read call that returned a CAN node's frame.");
  s.each(is_can_node, [&](const Report& r) {
    summary_samples(w, "vigil_can_read_seconds", r.name, distribution_field(r, "read_time"));
  });
  w.family("vigil_can_silence_seconds", Type::Gauge,
           "Time since the latest frame received from a CAN node (absent when never received).");
  s.each(is_can_node, [&](const Report& r) {
    if (auto silence = duration_field(r, "silence")) {
      w.sample("vigil_can_silence_seconds", r.name, {}, seconds(*silence));
    }
  });
}

void can_group_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_can_group_frames_total", Type::Counter,
           "CAN frames of a group's nodes, both directions.");
  s.each(is_can_group, [&](const Report& r) {
    if (auto frames = count_field(r, "frames")) {
      w.sample_u("vigil_can_group_frames_total", r.name, {}, *frames);
    }
  });
  w.family("vigil_can_group_gap_seconds", Type::Histogram,
           "Time between consecutive frames of each member of a CAN group, merged, by "
           "direction (absent when not collected).");
  s.each(is_can_group, [&](const Report& r) {
    const CanHistograms* h = s.snap.can_histograms_of(r);
    if (h == nullptr) return;
    if (h->rx_gap) {
      direction_histogram_samples(w, "vigil_can_group_gap_seconds", r.name, "rx", &*h->rx_gap, 0,
                                  0.0);
    }
    if (h->tx_gap) {
      direction_histogram_samples(w, "vigil_can_group_gap_seconds", r.name, "tx", &*h->tx_gap, 0,
                                  0.0);
    }
  });
}

// CAN buses: their load as canbusload counts it (vigil/can/protocol.hpp), from the numbers the
// CAN extension publishes beside the bus reports (`MetricsSnapshot::can_buses`).
void can_bus_families(const Section& s) {
  Writer& w = s.w;
  constexpr std::array<std::string_view, 3> kDirections{"rx", "tx", "all"};
  w.family("vigil_can_bus_frames_total", Type::Counter,
           "CAN frames on a bus by direction: rx, tx, all (error frames excluded).");
  s.each(is_can_bus, [&](const Report& r) {
    const CanBusLoads* b = s.snap.can_bus_of(r);
    if (b == nullptr) return;
    for (std::size_t d = 0; d < 3; ++d) {
      w.sample_u("vigil_can_bus_frames_total", r.name, {{"direction", kDirections[d]}},
                 b->load[0][d].frames);
    }
  });
  w.family("vigil_can_bus_bit_times_total", Type::Counter,
           "Bits the frames of a CAN bus occupied on the wire, by direction and stuffing count "
           "(none, worst, exact: canbusload's three modes).");
  s.each(is_can_bus, [&](const Report& r) {
    const CanBusLoads* b = s.snap.can_bus_of(r);
    if (b == nullptr) return;
    for (std::size_t m = 0; m < can::kStuffingModes; ++m) {
      const std::string_view stuffing = can::to_string(static_cast<can::Stuffing>(m));
      for (std::size_t d = 0; d < 3; ++d) {
        w.sample_u("vigil_can_bus_bit_times_total", r.name,
                   {{"direction", kDirections[d]}, {"stuffing", stuffing}}, b->load[m][d].bits);
      }
    }
  });
  w.family("vigil_can_bus_load_ratio", Type::Gauge,
           "Load of a CAN bus, fraction of its bitrate (1 = 100 %), by direction and window "
           "(last_second, 1m, 5m, 15m, peak, mean), in the stuffing count the bus is judged by; "
           "absent without a bitrate.");
  s.each(is_can_bus, [&](const Report& r) {
    const CanBusLoads* b = s.snap.can_bus_of(r);
    if (b == nullptr) return;
    const auto& mode = b->load[static_cast<std::size_t>(b->judged)];
    const std::string_view stuffing = can::to_string(b->judged);
    for (std::size_t d = 0; d < 3; ++d) {
      const can::BusLoad& l = mode[d];
      if (!l.known) continue;
      const std::pair<std::string_view, double> windows[] = {{"last_second", l.last_second},
                                                             {"1m", l.avg_1m},
                                                             {"5m", l.avg_5m},
                                                             {"15m", l.avg_15m},
                                                             {"peak", l.peak},
                                                             {"mean", l.mean}};
      for (const auto& [window, percent] : windows) {
        w.sample("vigil_can_bus_load_ratio", r.name,
                 {{"direction", kDirections[d]}, {"window", window}, {"stuffing", stuffing}},
                 percent / 100.0);
      }
    }
  });
}

// CAN buses whose interface is read through netlink (`buses.<bus>.interface`): the controller as
// the driver reports it, from the bus unit's fields (vigil/can/can_link.hpp).
void can_link_families(const Section& s) {
  Writer& w = s.w;
  w.family("vigil_can_bus_controller_state", Type::Gauge,
           "State of a CAN controller read through netlink (enum can_state: 0 error active, 1 "
           "error warning, 2 error passive, 3 bus off, 4 stopped, 5 sleeping).");
  s.each(is_can_bus, [&](const Report& r) {
    if (auto v = count_field(r, "controller_state_code")) {
      w.sample_u("vigil_can_bus_controller_state", r.name, {}, *v);
    }
  });
  w.family("vigil_can_bus_error_counter", Type::Gauge,
           "Transmit and receive error counters of a CAN controller read through netlink.");
  s.each(is_can_bus, [&](const Report& r) {
    if (auto v = count_field(r, "link_tx_error_counter")) {
      w.sample_u("vigil_can_bus_error_counter", r.name, {{"direction", "tx"}}, *v);
    }
    if (auto v = count_field(r, "link_rx_error_counter")) {
      w.sample_u("vigil_can_bus_error_counter", r.name, {{"direction", "rx"}}, *v);
    }
  });
  w.family("vigil_can_bus_restarts_total", Type::Counter,
           "Restarts of a CAN controller (can_device_stats, read through netlink).");
  s.each(is_can_bus, [&](const Report& r) {
    if (auto v = count_field(r, "link_restarts")) {
      w.sample_u("vigil_can_bus_restarts_total", r.name, {}, *v);
    }
  });
  w.family("vigil_can_bus_errors_total", Type::Counter,
           "Bus errors of a CAN controller (can_device_stats, read through netlink).");
  s.each(is_can_bus, [&](const Report& r) {
    if (auto v = count_field(r, "link_bus_errors")) {
      w.sample_u("vigil_can_bus_errors_total", r.name, {}, *v);
    }
  });
  w.family("vigil_can_bus_bitrate", Type::Gauge,
           "Bitrate a CAN bus's load is counted with, bit/s, by phase (nominal, data); "
           "configured or read through netlink.");
  s.each(is_can_bus, [&](const Report& r) {
    if (auto v = count_field(r, "bitrate")) {
      w.sample_u("vigil_can_bus_bitrate", r.name, {{"phase", "nominal"}}, *v);
    }
    if (auto v = count_field(r, "data_bitrate")) {
      w.sample_u("vigil_can_bus_bitrate", r.name, {{"phase", "data"}}, *v);
    }
  });
}

// Health supervisions (vigil/health): one unit each, its type (alive, deadline, logical) a label.
void supervision_families(const Section& s) {
  Writer& w = s.w;
  const auto type_of = [](const Report& r) {
    const Field* f = r.field("type");
    return f != nullptr && f->type == Field::Type::Text ? std::string_view(f->text)
                                                        : std::string_view();
  };
  const auto counter = [&](std::string_view family, std::string_view field, const char* help) {
    w.family(family, Type::Counter, help);
    s.each(is_supervision, [&](const Report& r) {
      if (auto n = count_field(r, field)) w.sample_u(family, r.name, {{"type", type_of(r)}}, *n);
    });
  };
  counter("vigil_supervision_checkpoints_total", "checkpoints",
          "Checkpoints (or cycles) a health supervision has seen, those a full port dropped "
          "included when their count is known.");
  counter("vigil_supervision_lost_total", "lost",
          "Checkpoint reports a full port dropped, found by gaps in the checkpoints' counts.");
  counter("vigil_supervision_evaluations_total", "evaluations",
          "Results a health supervision judged: reference cycles (alive), start/end pairs "
          "(deadline), transitions (logical).");
  counter("vigil_supervision_failures_total", "failures",
          "Failures of a health supervision (too few or too many indications, never started, "
          "deadline too early, missed or restarted, invalid transition).");
  counter("vigil_supervision_expirations_total", "expirations",
          "Times a health supervision became EXPIRED (failures beyond its tolerance).");
  w.family("vigil_supervision_failed", Type::Gauge,
           "Failures of a health supervision not yet taken back by correct results (FAILED while "
           "within its tolerance, EXPIRED beyond it).");
  s.each(is_supervision, [&](const Report& r) {
    if (auto n = count_field(r, "failed")) {
      w.sample_u("vigil_supervision_failed", r.name, {{"type", type_of(r)}}, *n);
    }
  });
  w.family("vigil_supervision_indications", Type::Gauge,
           "Indications an alive supervision counted: in the latest full reference cycle "
           "(window=\"last\") and in the current one so far (window=\"current\").");
  s.each(is_supervision, [&](const Report& r) {
    if (auto n = count_field(r, "last_cycle")) {
      w.sample_u("vigil_supervision_indications", r.name, {{"window", "last"}}, *n);
    }
    if (auto n = count_field(r, "this_cycle")) {
      w.sample_u("vigil_supervision_indications", r.name, {{"window", "current"}}, *n);
    }
  });
  w.family("vigil_supervision_deadline_seconds", Type::Gauge,
           "Time from start to end checkpoint of a deadline supervision: the latest pair "
           "(stat=\"last\"), the shortest and the longest so far (absent before the first pair).");
  s.each(is_supervision, [&](const Report& r) {
    for (const char* stat : {"last", "min", "max"}) {
      if (auto d = duration_field(r, stat)) {
        w.sample("vigil_supervision_deadline_seconds", r.name, {{"stat", stat}}, seconds(*d));
      }
    }
  });
  w.family("vigil_supervision_detection_seconds", Type::Gauge,
           "Time from a health supervision's latest fault (a reference cycle's end, a deadline's "
           "max) to its detection (absent before the first failure).");
  s.each(is_supervision, [&](const Report& r) {
    if (auto d = duration_field(r, "detected_after")) {
      w.sample("vigil_supervision_detection_seconds", r.name, {}, seconds(*d));
    }
  });
}

// Reactions (vigil/service/reactions.hpp): the reaction thread's unit, `vigil.reactions`.
void reaction_families(const Section& s) {
  Writer& w = s.w;
  const auto counter = [&](std::string_view family, std::string_view field, const char* help) {
    w.family(family, Type::Counter, help);
    s.each(is_reactions, [&](const Report& r) {
      if (auto n = count_field(r, field)) w.sample_u(family, r.name, {}, *n);
    });
  };
  counter("vigil_reactions_fired_total", "fired",
          "Reactions fired (each may take several actions), rate-limited ones not included.");
  counter("vigil_reactions_actions_total", "actions",
          "Actions taken (or logged in dry run): safe state, CAN frames, watchdog, handler calls.");
  counter("vigil_reactions_rate_limited_total", "rate_limited",
          "Triggers a reaction's min_interval suppressed.");
  counter("vigil_reactions_failed_total", "failed",
          "Actions that failed: a CAN writer refused, no outer watchdog, a handler threw.");
  counter("vigil_reactions_over_budget_total", "over_budget",
          "Handler calls that ran over their budget.");
  counter("vigil_reactions_dropped_total", "dropped",
          "Handler calls dropped because the reaction thread's queue was full.");
  w.family("vigil_safe_state_requested", Type::Gauge,
           "1 while the process's safe-state request stands (vigil/safe_state.hpp), else 0.");
  s.each(is_reactions, [&](const Report& r) {
    const Field* f = r.field("safe_state");
    if (f != nullptr) w.sample_u("vigil_safe_state_requested", r.name, {}, f->text == "no" ? 0 : 1);
  });
}

// Every family, section by section, in the order they are exposed.
using SectionWriter = void (*)(const Section&);
constexpr SectionWriter kSections[] = {
    process_families,           status_families,
    diagnosis_families,         component_placement_families,
    component_counter_families, component_histogram_families,
    component_gauge_families,   thread_families,
    supervisor_families,        monitor_families,
    can_node_families,          can_group_families,
    can_bus_families,           can_link_families,
    supervision_families,       reaction_families,
};

}  // namespace

void render_metrics(std::string& out, const MetricsSnapshot& snap, ExpositionFormat format) {
  out.reserve(out.size() + 512 + snap.reports.components.size() * 9000);
  Writer w(out, format);
  const Section s{w, snap};
  for (const SectionWriter write : kSections) write(s);
  w.end();
}

}  // namespace vigil::exporter
