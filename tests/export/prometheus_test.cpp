#include "vigil/export/prometheus.hpp"

#include <catch2/catch.hpp>
#include <map>
#include <set>

#include "export/exposition.hpp"
#include "monitor/harness.hpp"
#include "vigil/export/buckets.hpp"

using namespace vigil;
using namespace vigil::exporter;
using vigil::test::Exposition;
using vigil::test::parse_exposition;

namespace {

// Reports of every kind, with names that need escaping, and the aggregator's histograms.
MetricsSnapshot rich_snapshot() {
  static test::Harness h;
  static test::PeriodicProbe fast(h, "fast", kNanosPerMilli);
  static test::PeriodicProbe odd(h, "we\"ird\\name\nx\xff", 2 * kNanosPerMilli);
  static bool once = [] {
    fast.probe.work_ns = 30 * kNanosPerMicro;
    odd.probe.work_ns = 700 * kNanosPerMicro;
    for (int i = 0; i < 200; ++i) h.cycle(fast.activity);
    for (int i = 0; i < 50; ++i) h.cycle(odd.activity);
    return true;
  }();
  (void)once;
  MetricsSnapshot s;
  s.reports = h.step();
  s.histograms = collect_histograms(h.aggregator);
  s.wall_time_ns = 1'700'000'000'123'456'789;
  // A thread's OS counters on one component.
  for (Report& r : s.reports.components) {
    if (r.name == "fast") {
      r.thread = platform::ThreadStats{.tid = 42,
                                       .name = "t",
                                       .voluntary_switches = 3,
                                       .involuntary_switches = 4,
                                       .minor_faults = 5,
                                       .major_faults = 6,
                                       .user_time_ns = 1'500'000'000,
                                       .system_time_ns = 10'000'000};
    }
  }
  Report node;
  node.kind = ReportKind::Unit;
  node.unit_kind = "can_node";
  node.name = "can0/drive_5";
  node.state_label = "not responding";
  node.add_field(Field::of_count("frames_rx", 120));
  node.add_field(Field::of_count("frames_tx", 118));
  node.add_field(Field::of_distribution("rx_gap", StatsSummary{.count = 10,
                                                               .mean = 1e6,
                                                               .p50 = 900'000,
                                                               .p90 = 1'000'000,
                                                               .p99 = 1'100'000,
                                                               .p999 = 1'200'000}));
  node.add_field(Field::of_duration("silence", 250 * kNanosPerMilli));
  node.merge(StatusLevel::Error, "not responding for 250ms");
  s.reports.components.push_back(node);
  Report group;
  group.kind = ReportKind::Unit;
  group.unit_kind = "can_group";
  group.name = "can group left_arm";
  group.state_label = "degraded";
  group.add_field(Field::of_count("frames", 238));
  s.reports.components.push_back(group);
  // A deadline supervision that failed (the fields service::supervision_unit() gives it).
  Report sup;
  sup.kind = ReportKind::Unit;
  sup.unit_kind = "supervision";
  sup.name = "supervision sense_to_act";
  sup.state_label = "expired";
  sup.merge(StatusLevel::Error, "no drive.write within 2.000 ms of camera.frame");
  sup.add_field(Field::of_text("type", "deadline"));
  sup.add_field(Field::of_text("entities", "camera, drive"));
  sup.add_field(Field::of_count("checkpoints", 2001));
  sup.add_field(Field::of_count("lost", 3));
  sup.add_field(Field::of_count("evaluations", 1000));
  sup.add_field(Field::of_count("failures", 2));
  sup.add_field(Field::of_count("failed", 1));
  sup.add_field(Field::of_count("tolerance", 0));
  sup.add_field(Field::of_count("expirations", 1));
  sup.add_field(Field::of_duration("last", 1'500'000));
  sup.add_field(Field::of_duration("min", 900'000));
  sup.add_field(Field::of_duration("max", 2'500'000));
  sup.add_field(Field::of_text("last_failure", "deadline_missed"));
  sup.add_field(Field::of_duration("detected_after", 120'000));
  s.reports.components.push_back(sup);
  Report alive;
  alive.kind = ReportKind::Unit;
  alive.unit_kind = "supervision";
  alive.name = "supervision drive_rate";
  alive.state_label = "ok";
  alive.add_field(Field::of_text("type", "alive"));
  alive.add_field(Field::of_count("checkpoints", 500));
  alive.add_field(Field::of_count("last_cycle", 10));
  alive.add_field(Field::of_count("this_cycle", 4));
  s.reports.components.push_back(alive);
  // Their gap buckets: the node's gaps exact (samples), the group's from a histogram.
  const std::vector<Nanos> rx = {900'000, 1'000'000, 1'000'000, 1'100'000, 4'000'000};
  const std::vector<Nanos> tx = {10'000'000, 10'000'000};
  supervisor::RunningStats merged;
  for (Nanos v : rx) merged.add(v);
  s.can_histograms.push_back(CanHistograms{.name = "can group left_arm",
                                           .group = true,
                                           .rx_gap = reduce_to_buckets(merged),
                                           .tx_gap = std::nullopt});
  s.can_histograms.push_back(CanHistograms{.name = "can0/drive_5",
                                           .group = false,
                                           .rx_gap = reduce_samples_to_buckets(rx),
                                           .tx_gap = reduce_samples_to_buckets(tx)});
  return s;
}

std::set<std::string> family_names(const Exposition& e) {
  std::set<std::string> out;
  for (const auto& f : e.families) out.insert(f.name);
  return out;
}

}  // namespace

TEST_CASE("Label values are escaped and repaired to UTF-8", "[export][prometheus]") {
  std::string out;
  append_label_value(out, "a\\b\"c\nd");
  CHECK(out == R"(a\\b\"c\nd)");
  out.clear();
  append_label_value(out, "ok \xc3\xa9 bad \xff end \xe2\x82");
  CHECK(out == "ok \xc3\xa9 bad \xEF\xBF\xBD end \xEF\xBF\xBD\xEF\xBF\xBD");
  out.clear();
  append_label_value(out, "tab\tstays");
  CHECK(out == "tab\tstays");
}

TEST_CASE("Numbers are written as the formats want them", "[export][prometheus]") {
  const auto num = [](double v) {
    std::string s;
    append_number(s, v);
    return s;
  };
  CHECK(num(0) == "0");
  CHECK(num(12345678901234.0) == "12345678901234");
  CHECK(num(1e-6) == "1e-06");
  CHECK(num(0.5) == "0.5");
  CHECK(num(INFINITY) == "+Inf");
  CHECK(num(-INFINITY) == "-Inf");
  CHECK(num(NAN) == "NaN");
  CHECK(std::stod(num(0.1 + 0.2)) == 0.1 + 0.2);  // round-trips
}

TEST_CASE("The Accept header chooses the format", "[export][prometheus]") {
  CHECK(negotiate_format("") == ExpositionFormat::Prometheus);
  CHECK(negotiate_format("text/plain;version=0.0.4") == ExpositionFormat::Prometheus);
  CHECK(negotiate_format("*/*") == ExpositionFormat::Prometheus);
  // What Prometheus 2.42 sends.
  CHECK(negotiate_format("application/openmetrics-text;version=1.0.0,application/"
                         "openmetrics-text;version=0.0.1;q=0.75,text/plain;version=0.0.4;q=0.5,"
                         "*/*;q=0.1") == ExpositionFormat::OpenMetrics);
  CHECK(negotiate_format("text/plain, application/openmetrics-text; version=1.0.0; q=0.5") ==
        ExpositionFormat::OpenMetrics);
  CHECK(negotiate_format("application/openmetrics-text;q=0") == ExpositionFormat::Prometheus);
  CHECK(std::string(content_type(ExpositionFormat::OpenMetrics))
            .starts_with("application/openmetrics-text; version=1.0.0"));
  CHECK(std::string(content_type(ExpositionFormat::Prometheus))
            .starts_with("text/plain; version=0.0.4"));
}

TEST_CASE("Buckets follow the documented rule, cumulative, +Inf equals the count",
          "[export][prometheus][buckets]") {
  supervisor::RunningStats stats;
  const std::vector<Nanos> samples = {
      0,      500,       900,           1'000,          1'400,         2'000,
      33'000, 7'000'000, 9'999'999'999, 10'000'000'000, Nanos{1} << 41};
  for (Nanos v : samples) stats.add(v);
  const BucketCounts b = reduce_to_buckets(stats);
  CHECK(b.count == samples.size());
  // The rule: a sample counts under the first boundary >= the upper edge of its bucket.
  using H = supervisor::RunningStats::Histogram;
  for (std::size_t k = 0; k < kBucketBounds; ++k) {
    std::uint64_t expected = 0;
    for (Nanos v : samples) {
      if (v > H::kMaxTrackable) continue;
      if (H::bucket_highest(H::bucket_index(v)) <= kBucketBoundsNs[k]) ++expected;
    }
    INFO("le " << kBucketBoundsNs[k]);
    CHECK(b.cumulative[k] == expected);
    if (k > 0) CHECK(b.cumulative[k] >= b.cumulative[k - 1]);
  }
  CHECK(b.cumulative[0] == 3);                       // 0, 500, 900 (1000's bucket ends at 1007)
  CHECK(b.cumulative.back() == samples.size() - 3);  // above 10 s (bucket edge) and 2^41: +Inf only
  CHECK(b.sum_ns == Approx(stats.mean() * static_cast<double>(stats.count())));

  // A shift moves every edge (total time = user + overhead).
  supervisor::RunningStats one;
  one.add(900);
  CHECK(reduce_to_buckets(one).cumulative[0] == 1);
  CHECK(reduce_to_buckets(one, 200).cumulative[0] == 0);
  CHECK(reduce_to_buckets(one, 200).cumulative[1] == 1);
  CHECK(reduce_to_buckets(supervisor::RunningStats{}).count == 0);
}

TEST_CASE("Every family has HELP and TYPE, in both formats", "[export][prometheus]") {
  const MetricsSnapshot snap = rich_snapshot();
  for (const bool om : {false, true}) {
    INFO((om ? "OpenMetrics" : "0.0.4"));
    const std::string text =
        render_metrics(snap, om ? ExpositionFormat::OpenMetrics : ExpositionFormat::Prometheus);
    const Exposition e = parse_exposition(text, om);  // throws on any unreadable line
    CHECK(e.eof == om);
    REQUIRE(e.families.size() > 40);
    for (const auto& f : e.families) {
      INFO(f.name);
      CHECK(f.has_help);
      CHECK(f.has_type);
      CHECK(!f.help.empty());
      CHECK(f.name.starts_with("vigil_"));
      CHECK(!f.samples.empty());
      if (f.type == "counter" && !om) CHECK(f.name.ends_with("_total"));
      if (f.type == "counter" && om) CHECK(!f.name.ends_with("_total"));
      if (om && f.name.ends_with("_seconds") && f.type != "info") CHECK(f.unit == "seconds");
      CHECK(f.name.find("_ns") == std::string::npos);  // base units only
    }
  }
}

TEST_CASE("Histograms are cumulative with +Inf equal to the count", "[export][prometheus]") {
  const MetricsSnapshot snap = rich_snapshot();
  const Exposition e = parse_exposition(render_metrics(snap, ExpositionFormat::Prometheus), false);
  int checked = 0;
  for (const auto& f : e.families) {
    if (f.type != "histogram") continue;
    std::map<std::string, std::vector<const test::Sample*>> buckets;
    std::map<std::string, double> counts;
    for (const auto& s : f.samples) {
      const std::string c = s.label("component") + "/" + s.label("direction");
      if (s.name == f.name + "_bucket") buckets[c].push_back(&s);
      if (s.name == f.name + "_count") counts[c] = s.value;
    }
    for (const auto& [component, bs] : buckets) {
      INFO(f.name << " " << component);
      REQUIRE(bs.size() == kBucketBounds + 1);
      double le = -1, previous = 0;
      for (const auto* b : bs) {
        const double this_le = b->label("le") == "+Inf" ? INFINITY : std::stod(b->label("le"));
        CHECK(this_le > le);
        CHECK(b->value >= previous);
        le = this_le;
        previous = b->value;
      }
      CHECK(bs.back()->label("le") == "+Inf");
      CHECK(bs.back()->value == counts.at(component));
      ++checked;
    }
  }
  CHECK(checked >= 8 + 3);  // 4 timing families x 2 components, CAN gaps rx, tx, group rx

  // The fast component's execution time (30 us per cycle) sits under le=3e-05 or the next one.
  const auto* exec = e.find("vigil_component_execution_seconds");
  REQUIRE(exec != nullptr);
  double at_20us = -1, at_50us = -1, count = -1;
  for (const auto& s : exec->samples) {
    if (s.label("component") != "fast") continue;
    if (s.label("le") == "2e-05") at_20us = s.value;
    if (s.label("le") == "5e-05") at_50us = s.value;
    if (s.name.ends_with("_count")) count = s.value;
  }
  CHECK(at_20us == 0);
  CHECK(count >= 199);
  CHECK(at_50us == count);
}

TEST_CASE("Label values round-trip through the exposition", "[export][prometheus]") {
  const MetricsSnapshot snap = rich_snapshot();
  const Exposition e = parse_exposition(render_metrics(snap, ExpositionFormat::OpenMetrics), true);
  const auto* status = e.find("vigil_component_status");
  REQUIRE(status != nullptr);
  std::set<std::string> names;
  for (const auto& s : status->samples) names.insert(s.label("component"));
  CHECK(names.count("we\"ird\\name\nx\xEF\xBF\xBD") == 1);
  CHECK(names.count("can0/drive_5") == 1);
  CHECK(names.count("vigil.supervisor") == 1);
  CHECK(names.count("vigil.monitor") == 1);
  for (const auto& s : status->samples) {
    if (s.label("component") == "can0/drive_5") CHECK(s.value == 2);
  }
  const auto* frames = e.find("vigil_can_frames");  // OpenMetrics: the counter's base name
  REQUIRE(frames != nullptr);
  REQUIRE(frames->samples.size() == 2);
  CHECK(frames->samples[0].label("direction") == "rx");
  CHECK(frames->samples[0].value == 120);
  const auto* cpu = e.find("vigil_thread_cpu_seconds");
  REQUIRE(cpu != nullptr);
  CHECK(cpu->samples.at(0).value == 1.5);
  const auto* build = e.find("vigil_build");
  REQUIRE(build != nullptr);
  CHECK(build->type == "info");
}

TEST_CASE("An empty snapshot is a valid exposition without empty families",
          "[export][prometheus]") {
  for (const bool om : {false, true}) {
    const std::string text = render_metrics(
        MetricsSnapshot{}, om ? ExpositionFormat::OpenMetrics : ExpositionFormat::Prometheus);
    const Exposition e = parse_exposition(text, om);
    CHECK(family_names(e) == std::set<std::string>{om ? "vigil_build" : "vigil_build_info",
                                                   "vigil_report_timestamp_seconds",
                                                   "vigil_reports"});
    CHECK(e.eof == om);
  }
}

TEST_CASE("CAN gaps are histograms per node and direction, and per group",
          "[export][prometheus][can]") {
  const MetricsSnapshot snap = rich_snapshot();
  for (const bool om : {false, true}) {
    const Exposition e = parse_exposition(
        render_metrics(snap, om ? ExpositionFormat::OpenMetrics : ExpositionFormat::Prometheus),
        om);
    const auto* gap = e.find("vigil_can_gap_seconds");
    REQUIRE(gap != nullptr);
    CHECK(gap->type == "histogram");
    CHECK(e.find("vigil_can_rx_gap_seconds") == nullptr);  // the summary it replaced
    std::map<std::string, double> at;                      // "direction le" -> cumulative count
    for (const auto& smp : gap->samples) {
      CHECK(smp.label("component") == "can0/drive_5");
      if (smp.name.ends_with("_bucket"))
        at[smp.label("direction") + " " + smp.label("le")] = smp.value;
      if (smp.name.ends_with("_count") && smp.label("direction") == "rx") CHECK(smp.value == 5);
      if (smp.name.ends_with("_sum") && smp.label("direction") == "rx") {
        CHECK(smp.value == Approx(8e-3));
      }
    }
    // Exact samples: 0.9 ms under le=0.001 with the two 1 ms ones; 1.1 ms under 0.0015.
    CHECK(at.at("rx 0.0007") == 0);
    CHECK(at.at("rx 0.001") == 3);
    CHECK(at.at("rx 0.0015") == 4);
    CHECK(at.at("rx 0.005") == 5);
    CHECK(at.at("rx +Inf") == 5);
    CHECK(at.at("tx 0.007") == 0);
    CHECK(at.at("tx 0.01") == 2);
    CHECK(at.at("tx +Inf") == 2);

    const auto* group = e.find("vigil_can_group_gap_seconds");
    REQUIRE(group != nullptr);
    CHECK(group->type == "histogram");
    double count = -1;
    for (const auto& smp : group->samples) {
      CHECK(smp.label("component") == "can group left_arm");
      CHECK(smp.label("direction") == "rx");  // no tx gaps in the group
      if (smp.name.ends_with("_count")) count = smp.value;
    }
    CHECK(count == 5);
  }

  // Without buckets (a publisher that collected none): the node's rx count and sum from its
  // report; no group family.
  MetricsSnapshot bare = rich_snapshot();
  bare.can_histograms.clear();
  const Exposition e = parse_exposition(render_metrics(bare, ExpositionFormat::Prometheus), false);
  const auto* gap = e.find("vigil_can_gap_seconds");
  REQUIRE(gap != nullptr);
  REQUIRE(gap->samples.size() == 3);  // +Inf, sum, count
  CHECK(gap->samples[0].label("le") == "+Inf");
  CHECK(gap->samples[0].value == 10);
  CHECK(e.find("vigil_can_group_gap_seconds") == nullptr);
}

TEST_CASE("Samples reduce to exact buckets", "[export][prometheus][buckets]") {
  const std::vector<Nanos> samples = {0, 999, 1'000, 1'001, 1'500, 7'000'000'000, 10'000'000'001};
  const BucketCounts b = reduce_samples_to_buckets(samples);
  CHECK(b.count == samples.size());
  CHECK(b.cumulative[0] == 3);                  // le 1 us: 0, 999, 1000
  CHECK(b.cumulative[1] == 5);                  // le 1.5 us
  CHECK(b.cumulative[kBucketBounds - 2] == 6);  // le 7 s
  CHECK(b.cumulative[kBucketBounds - 1] == 6);  // le 10 s: the last one only in +Inf
  CHECK(b.sum_ns == Approx(17'000'004'501.0));
  CHECK(reduce_samples_to_buckets({}).count == 0);
}

TEST_CASE("Health supervisions are served from their fields", "[export][prometheus][health]") {
  const MetricsSnapshot snap = rich_snapshot();
  const Exposition e = parse_exposition(render_metrics(snap, ExpositionFormat::Prometheus), false);
  const auto value = [&](const char* family, const char* component,
                         std::pair<const char*, const char*> label = {nullptr, nullptr}) {
    const auto* f = e.find(family);
    REQUIRE(f != nullptr);
    for (const auto& smp : f->samples) {
      if (smp.label("component") != component) continue;
      if (label.first != nullptr && smp.label(label.first) != label.second) continue;
      return smp.value;
    }
    FAIL("no sample of " << family << " for " << component);
    return 0.0;
  };
  const char* deadline = "supervision sense_to_act";
  CHECK(value("vigil_supervision_checkpoints_total", deadline, {"type", "deadline"}) == 2001);
  CHECK(value("vigil_supervision_lost_total", deadline) == 3);
  CHECK(value("vigil_supervision_evaluations_total", deadline) == 1000);
  CHECK(value("vigil_supervision_failures_total", deadline) == 2);
  CHECK(value("vigil_supervision_expirations_total", deadline) == 1);
  CHECK(value("vigil_supervision_failed", deadline) == 1);
  CHECK(value("vigil_supervision_deadline_seconds", deadline, {"stat", "max"}) == Approx(0.0025));
  CHECK(value("vigil_supervision_deadline_seconds", deadline, {"stat", "last"}) == Approx(0.0015));
  CHECK(value("vigil_supervision_detection_seconds", deadline) == Approx(0.00012));
  CHECK(value("vigil_supervision_indications", "supervision drive_rate", {"window", "last"}) == 10);
  CHECK(value("vigil_supervision_indications", "supervision drive_rate", {"window", "current"}) ==
        4);
  CHECK(value("vigil_component_status", deadline, {"kind", "supervision"}) == 2);
  CHECK(value("vigil_component_state", deadline, {"state", "expired"}) == 1);
  // What a supervision does not have is absent, not zero.
  for (const auto& smp : e.find("vigil_supervision_deadline_seconds")->samples) {
    CHECK(smp.label("component") != "supervision drive_rate");
  }
}

TEST_CASE("CAN units are served from their fields, under CAN names", "[export][prometheus][can]") {
  const MetricsSnapshot snap = rich_snapshot();
  const Exposition e = parse_exposition(render_metrics(snap, ExpositionFormat::Prometheus), false);
  const auto* silence = e.find("vigil_can_silence_seconds");
  REQUIRE(silence != nullptr);
  REQUIRE(silence->samples.size() == 1);
  CHECK(silence->samples[0].label("component") == "can0/drive_5");
  CHECK(silence->samples[0].value == Approx(0.25));
  const auto* frames = e.find("vigil_can_group_frames_total");
  REQUIRE(frames != nullptr);
  REQUIRE(frames->samples.size() == 1);
  CHECK(frames->samples[0].value == 238);
  // Reports by kind: the monitor's kinds, then each unit kind the contributors named.
  const auto* kinds = e.find("vigil_reports");
  REQUIRE(kinds != nullptr);
  std::map<std::string, double> by_kind;
  for (const auto& smp : kinds->samples) by_kind[smp.label("kind")] = smp.value;
  CHECK(by_kind.at("can_node") == 1);
  CHECK(by_kind.at("can_group") == 1);
  CHECK(by_kind.at("monitor") == 1);
  CHECK(by_kind.count("unit") == 0);
  // A unit's state is its words; the components' state series are not repeated for it.
  std::size_t node_states = 0;
  for (const auto& smp : e.find("vigil_component_state")->samples) {
    if (smp.label("component") != "can0/drive_5") continue;
    ++node_states;
    CHECK(smp.label("state") == "not responding");
    CHECK(smp.label("kind") == "can_node");
  }
  CHECK(node_states == 1);
  // No component family shows the node.
  for (const char* family : {"vigil_component_cycles_total", "vigil_component_execution_seconds"}) {
    const auto* f = e.find(family);
    if (f == nullptr) continue;
    for (const auto& smp : f->samples) CHECK(smp.label("component") != "can0/drive_5");
  }
}
