#include "vigil/export/exemplars.hpp"

#include <catch2/catch.hpp>
#include <memory>
#include <string>
#include <vector>

#include "export/exposition.hpp"
#include "monitor/harness.hpp"
#include "vigil/export/prometheus.hpp"

using namespace vigil;
using namespace vigil::exporter;
using vigil::test::parse_exposition;

namespace {

constexpr ExemplarClock kClock{.monotonic_ns = 10 * kNanosPerSecond,
                               .unix_ns = 1'700'000'010'000'000'000};

ComponentHistograms component(std::uint32_t id, std::string name) {
  ComponentHistograms h;
  h.id = id;
  h.name = std::move(name);
  return h;
}

supervisor::WorstCycle worst(std::uint64_t cycle, Nanos value_ns, Nanos start_ns) {
  return {.cycle = cycle, .value_ns = value_ns, .start_ns = start_ns};
}

std::shared_ptr<const supervisor::FlightRecord> record(std::uint32_t id, std::uint64_t seq,
                                                       std::uint64_t first, std::uint64_t last) {
  auto r = std::make_shared<supervisor::FlightRecord>();
  r->component_id = id;
  r->event.seq = seq;
  for (std::uint64_t c = first; c <= last; ++c) r->cycles.push_back({.cycle = c});
  return r;
}

Event event(std::uint64_t seq, EventKind kind, std::uint32_t id, std::uint64_t cycle,
            Nanos fault_ns = 0, bool traced = false) {
  Event e;
  e.seq = seq;
  e.kind = kind;
  e.component_id = id;
  e.cycle = cycle;
  e.fault_ns = fault_ns;
  e.traced = traced;
  return e;
}

const BucketExemplar* find(const ComponentHistograms& h, TimingHistogram which,
                           std::uint8_t bucket) {
  for (const BucketExemplar& b : h.exemplars) {
    if (b.histogram == which && b.bucket == bucket) return &b;
  }
  return nullptr;
}

}  // namespace

TEST_CASE("bucket_of() puts a value in the first bucket whose bound holds it",
          "[export][exemplar]") {
  CHECK(bucket_of(-5) == 0);
  CHECK(bucket_of(0) == 0);
  CHECK(bucket_of(kBucketBoundsNs[0]) == 0);
  CHECK(bucket_of(kBucketBoundsNs[0] + 1) == 1);
  CHECK(bucket_of(kBucketBoundsNs[10]) == 10);
  CHECK(bucket_of(kBucketBoundsNs.back()) == kBucketBounds - 1);
  CHECK(bucket_of(kBucketBoundsNs.back() + 1) == kBucketBounds);  // +Inf
}

TEST_CASE("The book puts each worst cycle in its bucket and keeps the latest per bucket",
          "[export][exemplar]") {
  ExemplarBook book;
  std::vector<ComponentHistograms> hs{component(1, "motor")};
  const auto lat = static_cast<std::size_t>(TimingHistogram::Latency);
  hs[0].worst[lat].previous = worst(100, 40'000, 9 * kNanosPerSecond);
  hs[0].worst[lat].current = worst(900, 700'000, 9'500 * kNanosPerMilli);
  book.update(hs, {}, {}, kClock);
  REQUIRE(hs[0].exemplars.size() == 2);
  const BucketExemplar* small = find(hs[0], TimingHistogram::Latency, bucket_of(40'000));
  const BucketExemplar* large = find(hs[0], TimingHistogram::Latency, bucket_of(700'000));
  REQUIRE(small != nullptr);
  REQUIRE(large != nullptr);
  CHECK(small->exemplar.cycle == 100);
  CHECK(small->exemplar.value == Approx(40e-6));
  CHECK(small->exemplar.unix_ns == 1'700'000'009'000'000'000);
  CHECK(large->exemplar.cycle == 900);
  CHECK(large->exemplar.unix_ns == 1'700'000'009'500'000'000);
  CHECK(large->exemplar.trace == 0);

  // Next cycle: an older cycle in the same bucket does not replace it, a later one does; the
  // other bucket keeps its exemplar although no worst cycle fell in it this time.
  hs = {component(1, "motor")};
  hs[0].worst[lat].previous = worst(50, 600'000, 8 * kNanosPerSecond);
  hs[0].worst[lat].current = worst(1000, 40'001, 9'900 * kNanosPerMilli);
  book.update(hs, {}, {}, kClock);
  REQUIRE(hs[0].exemplars.size() == 2);
  CHECK(find(hs[0], TimingHistogram::Latency, bucket_of(700'000))->exemplar.cycle == 900);
  CHECK(find(hs[0], TimingHistogram::Latency, bucket_of(40'000))->exemplar.cycle == 1000);

  // A flight record frozen later that holds the cycle names it.
  hs = {component(1, "motor")};
  const std::vector<std::shared_ptr<const supervisor::FlightRecord>> frozen{
      record(2, 5, 800, 1000),  // another component's
      record(1, 7, 1, 899),     // does not hold cycle 900
      record(1, 9, 880, 950)};
  book.update(hs, {}, frozen, kClock);
  CHECK(find(hs[0], TimingHistogram::Latency, bucket_of(700'000))->exemplar.trace == 9);
  CHECK(find(hs[0], TimingHistogram::Latency, bucket_of(40'000))->exemplar.trace == 0);

  // A component that is gone is forgotten.
  hs = {component(2, "other")};
  book.update(hs, {}, {}, kClock);
  CHECK(book.size() == 1);
  CHECK(hs[0].exemplars.empty());
}

TEST_CASE("The overrun counter's exemplar is the latest overrun event, traced when it froze one",
          "[export][exemplar]") {
  ExemplarBook book;
  std::vector<ComponentHistograms> hs{component(3, "planner")};
  const std::vector<Event> events{
      event(4, EventKind::Overrun, 3, 40, 9 * kNanosPerSecond),
      event(5, EventKind::Exception, 3, 41),
      event(6, EventKind::OverrunLimit, 3, 44, 9'250 * kNanosPerMilli, true)};
  book.update(hs, events, {}, kClock);
  CHECK(hs[0].overrun.cycle == 44);
  CHECK(hs[0].overrun.value == 1);
  CHECK(hs[0].overrun.trace == 6);
  CHECK(hs[0].overrun.unix_ns == 1'700'000'009'250'000'000);
  // An older overrun reported later (another drain's) does not move it back.
  hs = {component(3, "planner")};
  const std::vector<Event> older{event(7, EventKind::Overrun, 3, 43)};
  book.update(hs, older, {}, kClock);
  CHECK(hs[0].overrun.cycle == 44);
}

TEST_CASE("OpenMetrics writes the exemplars on buckets and the overrun counter, 0.0.4 does not",
          "[export][exemplar][prometheus]") {
  test::Harness h;
  test::PeriodicProbe fast(h, "fast", kNanosPerMilli);
  for (int i = 0; i < 200; ++i) {
    if (i == 120) fast.probe.work_ns = 400 * kNanosPerMicro;  // the worst cycle: 121
    h.cycle(fast.activity);
    fast.probe.work_ns = 30 * kNanosPerMicro;
  }
  MetricsSnapshot s;
  s.reports = h.step();
  s.histograms = collect_histograms(h.aggregator);
  REQUIRE(s.histograms.size() == 1);
  const auto exec = static_cast<std::size_t>(TimingHistogram::Execution);
  REQUIRE(s.histograms[0].worst[exec].current.cycle == 121);
  const std::uint32_t id = s.histograms[0].id;
  ExemplarBook book;
  const std::vector<Event> events{event(3, EventKind::Overrun, id, 77, h.clock.now())};
  const std::vector<std::shared_ptr<const supervisor::FlightRecord>> frozen{
      record(id, 12, 100, 130)};
  book.update(s.histograms, events, frozen, ExemplarClock::now());

  const std::string om = render_metrics(s, ExpositionFormat::OpenMetrics);
  const auto e = parse_exposition(om, true);  // strict: throws on a malformed exemplar
  const auto* overruns = e.find("vigil_component_overruns");
  REQUIRE(overruns != nullptr);
  REQUIRE(overruns->samples.size() == 1);
  REQUIRE(overruns->samples[0].exemplar.has_value());
  CHECK(overruns->samples[0].exemplar->label("cycle") == "77");
  CHECK(overruns->samples[0].exemplar->label("trace").empty());  // nothing holds cycle 77
  CHECK(overruns->samples[0].exemplar->value == 1);
  CHECK(overruns->samples[0].exemplar->timestamp.has_value());

  const auto* execution = e.find("vigil_component_execution_seconds");
  REQUIRE(execution != nullptr);
  int with = 0;
  double previous_le = -INFINITY;
  for (const auto& sample : execution->samples) {
    if (sample.name != "vigil_component_execution_seconds_bucket") continue;
    const double le = test::parse_number(sample.label("le"));
    if (sample.exemplar) {
      ++with;
      // In its own bucket: above the bound before.
      CHECK(sample.exemplar->value > previous_le);
      if (sample.exemplar->label("cycle") == "121") {
        CHECK(sample.exemplar->value == Approx(400e-6));
        CHECK(sample.exemplar->label("trace") == "12");
      }
    }
    previous_le = le;
  }
  CHECK(with >= 1);
  CHECK(om.find("cycle=\"121\",trace=\"12\"") != std::string::npos);
  // Only counters' _total and histograms' _bucket lines carry them (the parser checks it too).
  for (const auto& f : e.families) {
    for (const auto& sample : f.samples) {
      if (sample.exemplar) {
        CHECK((sample.name.ends_with("_bucket") || sample.name.ends_with("_total")));
      }
    }
  }

  const std::string text = render_metrics(s, ExpositionFormat::Prometheus);
  CHECK(text.find(" # {") == std::string::npos);
  CHECK_NOTHROW(parse_exposition(text, false));
}

TEST_CASE("The strict reader refuses malformed exemplars", "[export][exemplar]") {
  const std::string head =
      "# HELP x_seconds h\n# TYPE x_seconds histogram\n# UNIT x_seconds seconds\n";
  const auto om = [&](const std::string& bucket_line) {
    return head + bucket_line + "\nx_seconds_bucket{le=\"+Inf\"} 2\nx_seconds_sum 1\n" +
           "x_seconds_count 2\n# EOF\n";
  };
  CHECK_NOTHROW(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # {cycle=\"5\"} 0.5"), true));
  CHECK_NOTHROW(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # {} 0.5 1700000000.123"), true));
  // Above its bucket's le.
  CHECK_THROWS(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # {cycle=\"5\"} 1.5"), true));
  // Longer than 128 code points.
  CHECK_THROWS(parse_exposition(
      om("x_seconds_bucket{le=\"1\"} 2 # {trace=\"" + std::string(124, 'a') + "\"} 0.5"), true));
  // No label set, bad value, bad label name, a label twice.
  CHECK_THROWS(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # 0.5"), true));
  CHECK_THROWS(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # {} x"), true));
  CHECK_THROWS(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # {1a=\"b\"} 0.5"), true));
  CHECK_THROWS(parse_exposition(om("x_seconds_bucket{le=\"1\"} 2 # {a=\"b\",a=\"c\"} 0.5"), true));
  // On a _sum line, and in the 0.0.4 format.
  CHECK_THROWS(parse_exposition(head + "x_seconds_bucket{le=\"+Inf\"} 2\n" +
                                    "x_seconds_sum 1 # {} 1\nx_seconds_count 2\n# EOF\n",
                                true));
  CHECK_THROWS(parse_exposition(
      "# HELP c_total h\n# TYPE c_total counter\nc_total 3 # {cycle=\"1\"} 1\n", false));
}
