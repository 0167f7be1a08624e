#include "vigil/can/can_statistics.hpp"

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>
#include <thread>

#include "can_test_support.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/platform/clock.hpp"

using namespace vigil::can;
using vigil::kNanosPerMicro;
using vigil::kNanosPerMilli;
using vigil::kNanosPerSecond;
using vigil::Nanos;
using vigil::StatusLevel;
using vigil::can::test::frame;
using vigil::can::test::Pipeline;

TEST_CASE("Fairness: 8 nodes at 1 kHz, a port of 16, a supervisor at 10 Hz", "[can][fairness]") {
  // The original downsampled by the full port: nodes that came later never got through and
  // looked dead. Here counts and liveness come from the sniffer's table: exact for every node.
  Pipeline<16> p({.node_map = NodeMap::canopen()});
  CanMonitor monitor;  // built-in thresholds: not responding after 1 s
  CanConfig config;
  config.defaults.not_responding_after_ns = 100 * kNanosPerMilli;
  monitor.set_config(config);

  constexpr int kNodes = 8;
  constexpr Nanos kStart = 1'000 * kNanosPerSecond;
  Nanos now = kStart;
  for (int ms = 1; ms <= 1000; ++ms) {
    now = kStart + ms * kNanosPerMilli;
    for (int n = 1; n <= kNodes; ++n) {
      // Each node's TPDO1, read in node order within the millisecond, 20 us per read.
      const Frame f = frame(0x180 + static_cast<std::uint32_t>(n), now + n * 20 * kNanosPerMicro);
      p.read(f, 15 * kNanosPerMicro);
    }
    if (ms % 100 == 0) p.supervisor.step();  // 10 Hz
  }
  const CanSnapshot s = p.aggregator.snapshot();
  CHECK(s.totals.frames == 8000);
  CHECK(s.totals.dropped == 8000 - 10 * 16);  // 98 % of the records were dropped
  CHECK(s.records == 10 * 16);
  REQUIRE(s.nodes.size() == kNodes);
  for (const NodeStats& n : s.nodes) {
    INFO("node " << n.node);
    CHECK(n.frames == 1000);  // exact
    CHECK(n.exact_count);
    CHECK(n.last_ns == now + static_cast<Nanos>(n.node) * 20 * kNanosPerMicro);
    CHECK(n.records > 0);
    // Every sampled gap is a true gap between consecutive frames: exactly 1 ms.
    CHECK(n.gap_ns.min == kNanosPerMilli);
    CHECK(n.gap_ns.max == kNanosPerMilli);
    CHECK(n.io_ns.max == 15 * kNanosPerMicro);
  }
  const CanReport r = monitor.evaluate(p.aggregator, now + 200 * kNanosPerMicro);
  REQUIRE(r.nodes.size() == kNodes);
  for (const NodeReport& n : r.nodes) {
    INFO(n.name << ": " << n.status.summary());
    CHECK(n.status.level() == StatusLevel::Ok);  // responding
    CHECK(n.silence_ns >= 0);
    CHECK(n.silence_ns < kNanosPerMilli);
    CHECK(n.rx->frames == 1000);
  }
  CHECK(r.status.level() == StatusLevel::Ok);
  CHECK(r.status.summary().find("dropped by full ports") != std::string::npos);
}

TEST_CASE("Fairness in real time: I/O thread at 1 kHz, supervisor thread at 10 Hz",
          "[can][fairness][threads]") {
  CanRegistry registry;
  Sniffer<16> sniffer(registry, "bus0", {.node_map = NodeMap::canopen()});
  CanAggregator aggregator(registry);
  CanDrainLoop supervisor(registry.ports(), aggregator, {.period_ns = 100 * kNanosPerMilli});
  REQUIRE(supervisor.start().has_value());
  std::atomic<bool> stop{false};
  std::uint64_t sent = 0;
  std::thread io([&] {
    Nanos next = vigil::platform::now_ns();
    const Nanos end = next + kNanosPerSecond;
    while (next < end) {
      for (std::uint32_t n = 1; n <= 8; ++n) {
        const Nanos t0 = vigil::platform::now_ns();
        const Nanos t1 = vigil::platform::now_ns();
        sniffer.on_read(frame(0x180 + n, t1), t0, t1);
        ++sent;
      }
      next += kNanosPerMilli;
      vigil::platform::sleep_until(next);
    }
    stop.store(true);
  });
  io.join();
  supervisor.stop();  // joins after one last full drain
  const CanSnapshot s = aggregator.snapshot();
  CHECK(s.totals.frames == sent);
  REQUIRE(s.nodes.size() == 8);
  for (const NodeStats& n : s.nodes) {
    CHECK(n.frames == sent / 8);
    CHECK(n.exact_count);
  }
  CanConfig config;
  config.defaults.not_responding_after_ns = 200 * kNanosPerMilli;
  const CanMonitor monitor(config);
  const CanReport r = monitor.evaluate(aggregator, vigil::platform::now_ns());
  for (const NodeReport& n : r.nodes) {
    INFO(n.name << ": " << n.status.summary());
    CHECK(n.status.level() == StatusLevel::Ok);
  }
}

TEST_CASE("Per-node statistics: counts in and out, I/O times, gaps", "[can][statistics]") {
  Pipeline<1024> p({.node_map = NodeMap::canopen()});
  // Node 5: we write an RPDO every 10 ms (write takes 40 us), it answers TPDO1 every 10 ms
  // (read takes 25 us), except one late answer (13 ms).
  Nanos t = 0;
  for (int i = 0; i < 10; ++i) {
    t += 10 * kNanosPerMilli;
    p.write(frame(0x205, t), 40 * kNanosPerMicro);
    const Nanos late = i == 6 ? 3 * kNanosPerMilli : 0;
    p.read(frame(0x185, t + kNanosPerMilli + late), 25 * kNanosPerMicro);
  }
  const CanSnapshot s = p.step();
  const NodeStats* rx = s.find_node(0, 5, Direction::Rx);
  const NodeStats* tx = s.find_node(0, 5, Direction::Tx);
  REQUIRE(rx != nullptr);
  REQUIRE(tx != nullptr);
  CHECK(rx->frames == 10);
  CHECK(tx->frames == 10);
  CHECK(rx->ids == 1);
  CHECK(rx->io_ns.mean == 25'000.0);
  CHECK(tx->io_ns.max == 40 * kNanosPerMicro);
  CHECK(tx->gap_ns.count == 9);
  CHECK(tx->gap_ns.min == 10 * kNanosPerMilli);
  CHECK(tx->gap_ns.max == 10 * kNanosPerMilli);
  CHECK(rx->gap_ns.min == 7 * kNanosPerMilli);
  CHECK(rx->gap_ns.max == 13 * kNanosPerMilli);
  CHECK(rx->first_ns == 11 * kNanosPerMilli);
  const IdStats* id = s.find_id(0, 0x185, false, Direction::Rx);
  REQUIRE(id != nullptr);
  CHECK(id->node == 5);
  CHECK(id->function == 3);
  CHECK(id->frames == 10);
  CHECK(id->records == 10);
  CHECK(id->last_data[0] == 0x01);
  CHECK(s.find_id(0, 0x185, true, Direction::Rx) == nullptr);  // the extended id 0x185 is another

  // Summary rows: all Rx and all Tx.
  REQUIRE(s.categories.size() == 2);
  CHECK(s.categories[0].name == "all");
  CHECK(s.categories[0].direction == Direction::Rx);
  CHECK(s.categories[0].frames == 10);
  CHECK(s.categories[1].direction == Direction::Tx);
  CHECK(s.categories[1].io_ns.mean == 40'000.0);
}

TEST_CASE("Groups aggregate their members' statistics", "[can][statistics][groups]") {
  Pipeline<4096> p({.node_map = NodeMap::canopen()});
  // Nodes 11-14 ("left arm") every 1 ms with gaps of 1 ms; nodes 21, 22 every 2 ms.
  for (int ms = 1; ms <= 100; ++ms) {
    const Nanos t = ms * kNanosPerMilli;
    for (std::uint32_t n = 11; n <= 14; ++n) p.read(frame(0x180 + n, t), 10 * kNanosPerMicro);
    if (ms % 2 == 0) {
      p.read(frame(0x180 + 21, t), 30 * kNanosPerMicro);
      p.read(frame(0x180 + 22, t), 50 * kNanosPerMicro);
    }
  }
  const std::vector<GroupSpec> groups{
      {.name = "left_arm", .node_ranges = {{11, 14}}},
      {.name = "brand_x", .nodes = {21, 22}},
      {.name = "spare", .bus = 1, .nodes = {11}},  // another bus: no member seen
  };
  const CanSnapshot s = p.step(groups);
  REQUIRE(s.categories.size() == 4);
  const CategoryStats& all = s.categories[0];
  CHECK(all.name == "all");
  CHECK(all.nodes == 6);
  CHECK(all.frames == 500);
  const CategoryStats& arm = s.categories[1];
  CHECK(arm.name == "left_arm");
  CHECK(arm.group);
  CHECK(arm.nodes == 4);
  CHECK(arm.frames == 400);
  CHECK(arm.records == 400);
  CHECK(arm.gap_ns.count == 4 * 99);
  CHECK(arm.gap_ns.min == kNanosPerMilli);
  CHECK(arm.gap_ns.max == kNanosPerMilli);
  CHECK(arm.io_ns.mean == 10'000.0);
  const CategoryStats& brand = s.categories[2];
  CHECK(brand.name == "brand_x");
  CHECK(brand.frames == 100);
  CHECK(brand.gap_ns.min == 2 * kNanosPerMilli);
  CHECK(brand.io_ns.min == 30 * kNanosPerMicro);
  CHECK(brand.io_ns.max == 50 * kNanosPerMicro);
  CHECK(brand.io_ns.mean == 40'000.0);
  const CategoryStats& spare = s.categories[3];
  CHECK(spare.name == "spare");
  CHECK(spare.frames == 0);
  CHECK(spare.nodes == 0);

  CHECK(groups[0].contains(0, 12));
  CHECK_FALSE(groups[0].contains(0, 15));
  CHECK(groups[2].contains(1, 11));
  CHECK_FALSE(groups[2].contains(0, 11));
}

TEST_CASE("Exact percentiles keep every gap", "[can][statistics]") {
  Pipeline<4096> approx({}, {});
  Pipeline<4096> exact({}, {.exact_percentiles = true});
  // 101 gaps: 1 ms, 2 ms, ... 101 ms (+ 7 ns so that no value is a bucket bound).
  Nanos t = 0;
  for (int i = 0; i <= 101; ++i) {
    approx.read(frame(0x10, t));
    exact.read(frame(0x10, t));
    t += (i + 1) * kNanosPerMilli + 7;
  }
  const CanSnapshot sa = approx.step();
  const CanSnapshot se = exact.step();
  const IdStats* ia = sa.find_id(0, 0x10, false, Direction::Rx);
  const IdStats* ie = se.find_id(0, 0x10, false, Direction::Rx);
  REQUIRE(ia != nullptr);
  REQUIRE(ie != nullptr);
  CHECK(ie->gap_exact);
  CHECK_FALSE(ia->gap_exact);
  CHECK(ie->gap_ns.count == 101);
  CHECK(ie->gap_ns.p50 == 51 * kNanosPerMilli + 7);  // nearest rank 51 of 101
  CHECK(ie->gap_ns.p90 == 91 * kNanosPerMilli + 7);
  CHECK(ie->gap_ns.min == ia->gap_ns.min);
  CHECK(ie->gap_ns.max == ia->gap_ns.max);
  // The histogram's median is an upper bound within 2^-5.
  CHECK(ia->gap_ns.p50 >= ie->gap_ns.p50);
  CHECK(static_cast<double>(ia->gap_ns.p50) <=
        static_cast<double>(ie->gap_ns.p50) * (1 + 1.0 / 32));

  std::vector<Nanos> v{5, 1, 4, 2, 3};
  const vigil::StatsSummary e = exact_summary(v);
  CHECK(e.count == 5);
  CHECK(e.min == 1);
  CHECK(e.max == 5);
  CHECK(e.p50 == 3);
  CHECK(e.mean == 3.0);
  std::vector<Nanos> none;
  CHECK(exact_summary(none).count == 0);
}

TEST_CASE("Exact percentiles by selection equal those of a full sort", "[can][statistics]") {
  // exact_summary selects the four ranks with nth_element; a sorted copy is the reference
  // (nearest rank: the smallest sample with at least q * n samples <= it).
  std::mt19937_64 rng(48);
  for (const std::size_t n : {1U, 2U, 3U, 10U, 99U, 1000U, 1001U, 20000U}) {
    for (const Nanos spread : {Nanos{3}, Nanos{1000000}}) {  // many ties, then few
      std::vector<Nanos> v(n);
      std::uniform_int_distribution<Nanos> value(0, spread);
      for (Nanos& x : v) x = value(rng);
      std::vector<Nanos> sorted = v;
      std::sort(sorted.begin(), sorted.end());
      const auto rank = [&](double q) {
        const auto need = static_cast<std::size_t>(std::ceil(q * static_cast<double>(n)));
        return sorted[std::max<std::size_t>(need, 1) - 1];
      };
      const vigil::StatsSummary e = exact_summary(v);
      INFO("n " << n << " spread " << spread);
      CHECK(e.count == n);
      CHECK(e.min == sorted.front());
      CHECK(e.max == sorted.back());
      CHECK(e.p50 == rank(0.5));
      CHECK(e.p90 == rank(0.9));
      CHECK(e.p99 == rank(0.99));
      CHECK(e.p999 == rank(0.999));
      std::sort(v.begin(), v.end());
      CHECK(v == sorted);  // reordered, not changed
    }
  }
}

TEST_CASE("Statistics of a sniffer survive its departure", "[can][statistics]") {
  CanRegistry registry;
  CanAggregator aggregator(registry);
  CanDrainLoop supervisor(registry.ports(), aggregator);
  std::uint32_t port = 0;
  {
    Sniffer<4> sniffer(registry, "short-lived");
    port = sniffer.port_id();
    for (int i = 0; i < 100; ++i) sniffer.on_read(frame(0x42, i), i, i);
  }  // gone before the supervisor ever ran
  supervisor.step();
  supervisor.step();
  const CanSnapshot s = aggregator.snapshot();
  REQUIRE(s.sniffers.size() == 1);
  CHECK_FALSE(s.sniffers[0].alive);
  CHECK(s.sniffers[0].name == "short-lived");
  CHECK(s.totals.frames == 100);
  CHECK(s.totals.dropped == 96);
  REQUIRE(s.ids.size() == 1);
  CHECK(s.ids[0].frames == 100);
  CHECK(s.ids[0].records == 4);
  CHECK(registry.find(port) == nullptr);  // released once read
}

TEST_CASE("Two sniffers on two buses", "[can][statistics]") {
  CanRegistry registry;
  Sniffer<64> a(registry, "a");
  Sniffer<64> b(registry, "b");
  CanAggregator aggregator(registry);
  CanDrainLoop supervisor(registry.ports(), aggregator);
  for (int i = 0; i < 10; ++i) {
    a.on_read(frame(0x100, i, 0), i, i);
    b.on_read(frame(0x100, i, 1), i, i);
    b.on_read(frame(0x100, i, 1), i, i);
  }
  supervisor.step();
  const CanSnapshot s = aggregator.snapshot();
  CHECK(s.totals.frames == 30);
  REQUIRE(s.ids.size() == 2);
  CHECK(s.ids[0].bus == 0);
  CHECK(s.ids[0].frames == 10);
  CHECK(s.ids[1].bus == 1);
  CHECK(s.ids[1].frames == 20);
  CHECK(s.sniffers.size() == 2);
}

TEST_CASE("Gap distributions are visited per node and per group, live and exact",
          "[can][statistics][groups]") {
  for (const bool exact : {false, true}) {
    INFO((exact ? "exact" : "live"));
    Pipeline<4096> p({.node_map = NodeMap::canopen()}, {.exact_percentiles = exact});
    // Nodes 11, 12 answer every 1 ms; we write to node 11 every 2 ms; node 21 every 3 ms.
    for (int ms = 1; ms <= 60; ++ms) {
      const Nanos t = ms * kNanosPerMilli;
      p.read(frame(0x180 + 11, t));
      p.read(frame(0x180 + 12, t));
      if (ms % 2 == 0) p.write(frame(0x200 + 11, t));
      if (ms % 3 == 0) p.read(frame(0x180 + 21, t));
    }
    p.read(frame(0x080, 61 * kNanosPerMilli));  // SYNC: the frames of no node
    p.read(frame(0x080, 62 * kNanosPerMilli));
    static_cast<void>(p.step());
    const std::vector<GroupSpec> groups{{.name = "arm", .nodes = {11, 12}},
                                        {.name = "empty", .nodes = {99}}};
    struct Seen {
      std::string group;
      std::uint32_t node;
      Direction direction;
      std::uint64_t count;
      Nanos min;
      Nanos max;
    };
    std::vector<Seen> seen;
    p.aggregator.visit_gap_distributions(groups, [&](const GapDistribution& d) {
      CHECK((d.stats == nullptr) == exact);
      CHECK((d.samples.empty()) == !exact);
      Nanos lo = 0;
      Nanos hi = 0;
      if (d.stats != nullptr) {
        lo = d.stats->min();
        hi = d.stats->max();
        // Live, a distribution holds the buckets of the range it has seen, not all 1,152: each
        // here sees one gap (1, 2 or 3 ms), one power of two of values, one chunk of 32 buckets.
        CHECK(d.stats->histogram().allocated_buckets() <= 2 * 32);
        CHECK(d.stats->histogram().allocated_buckets() > 0);
      } else {
        lo = *std::min_element(d.samples.begin(), d.samples.end());
        hi = *std::max_element(d.samples.begin(), d.samples.end());
      }
      seen.push_back({std::string(d.group), d.node, d.direction, d.count(), lo, hi});
    });
    // Nodes by (bus, node, direction) with the frames of no node (kNoNode) last, then the
    // groups with gaps (none for "empty").
    REQUIRE(seen.size() == 7);
    CHECK(seen[0].node == 11);
    CHECK(seen[0].direction == Direction::Rx);
    CHECK(seen[0].count == 59);
    CHECK(seen[0].min == kNanosPerMilli);
    CHECK(seen[1].node == 11);
    CHECK(seen[1].direction == Direction::Tx);
    CHECK(seen[1].count == 29);
    CHECK(seen[1].min == 2 * kNanosPerMilli);
    CHECK(seen[2].node == 12);
    CHECK(seen[3].node == 21);
    CHECK(seen[3].count == 19);
    CHECK(seen[3].max == 3 * kNanosPerMilli);
    CHECK(seen[4].group.empty());
    CHECK(seen[4].node == kNoNode);
    CHECK(seen[5].group == "arm");
    CHECK(seen[5].direction == Direction::Rx);
    CHECK(seen[5].count == 2 * 59);  // the members' gaps, merged
    CHECK(seen[5].max == kNanosPerMilli);
    CHECK(seen[6].group == "arm");
    CHECK(seen[6].direction == Direction::Tx);
    CHECK(seen[6].count == 29);
  }
}
