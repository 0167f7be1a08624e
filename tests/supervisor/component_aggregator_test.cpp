#include "vigil/supervisor/component_aggregator.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <catch2/catch.hpp>
#include <cmath>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "support/cycle_record.hpp"
#include "support/fake_clock.hpp"
#include "support/probe.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/task/instrumentation.hpp"

using namespace vigil;
using namespace vigil::supervisor;

TEST_CASE("The aggregator computes latency, period, user time and demangles exceptions",
          "[supervisor][aggregator]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {.overhead_sample_every = 1}, reg);
  p.work = [&] { fc.advance(250); };
  ManualActivity act(p, {.name = "m", .period_ns = 1000, .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  for (int i = 0; i < 100; ++i) {
    fc.set(act.next_release() + 40);
    act.step();
  }
  p.script.throw_update_at = 101;
  fc.set(act.next_release() + 40);
  act.step();
  ComponentAggregator agg({.warmup_ns = 0});  // every cycle in the statistics
  ComponentDrainLoop sup(reg, agg);
  sup.step();
  const auto s = agg.find("p");
  REQUIRE(s.has_value());
  CHECK(s->latency_ns.min == 40);
  CHECK(s->latency_ns.max == 40);
  CHECK(s->execution_ns.count == 101);
  CHECK(s->execution_ns.max == 250);
  CHECK(s->execution_ns.mean == Approx(250.0 * 100 / 101));  // the throwing cycle did no work
  CHECK(s->measured_period_ns.count == 100);
  CHECK(s->measured_period_ns.min == 1000);
  CHECK(s->measured_period_ns.max == 1000);
  CHECK(s->overhead_ns.count == 0);  // the fake clock does not move inside supervision
  CHECK(s->state == TaskState::Exception);
  CHECK(s->last_exception_type == "std::out_of_range");
  CHECK(s->counters.exceptions == 1);
  CHECK(s->info.name == std::string_view("p"));
}

TEST_CASE("Records of components that left are kept for a while, then forgotten",
          "[supervisor][aggregator]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  ComponentAggregator agg({.retain_left_ns = 5 * kNanosPerSecond, .clock = fc.clock()});
  ComponentDrainLoop sup(reg, agg);
  {
    Instrumentation c("short-lived", {}, reg);
    c.init();
    c.run([] {});
    sup.step();
  }
  sup.step();
  REQUIRE(agg.find("short-lived").has_value());
  CHECK_FALSE(agg.find("short-lived")->alive);
  fc.advance(6 * kNanosPerSecond);
  sup.step();
  CHECK_FALSE(agg.find("short-lived").has_value());
  CHECK(agg.size() == 0);
}

TEST_CASE("find_id() copies one record by id, alive or recently left", "[supervisor][aggregator]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  ComponentAggregator agg({.retain_left_ns = 5 * kNanosPerSecond, .clock = fc.clock()});
  ComponentDrainLoop sup(reg, agg);
  Instrumentation a("a", {}, reg);
  std::uint32_t gone_id = 0;
  {
    Instrumentation b("b", {}, reg);
    a.init();
    b.init();
    a.run([] {});
    b.run([] {});
    sup.step();
    REQUIRE(agg.find("b").has_value());
    gone_id = agg.find("b")->id;
    const auto by_id = agg.find_id(gone_id);
    REQUIRE(by_id.has_value());
    CHECK(by_id->name == "b");
    CHECK(by_id->id == gone_id);
    CHECK(by_id->alive);
    CHECK(by_id->samples == 1);
  }
  sup.step();
  const auto gone = agg.find_id(gone_id);
  REQUIRE(gone.has_value());
  CHECK(gone->name == "b");
  CHECK_FALSE(gone->alive);
  const auto alive = agg.find_id(agg.find("a")->id);
  REQUIRE(alive.has_value());
  CHECK(alive->name == "a");
  CHECK_FALSE(agg.find_id(gone_id + 100).has_value());
  CHECK_FALSE(agg.find_id(0).has_value());
}

TEST_CASE("Flight rings come from huge-page regions as their option says, and go back to them",
          "[supervisor][aggregator][recorder]") {
  constexpr std::size_t kRegion = platform::HugePageBlocks::kRegionBytes;
  // 16,384 cycles: 512 KiB rings, four to a region.
  constexpr std::size_t kCycles = 16 * 1024;
  struct System {
    explicit System(RingPages pages)
        : agg({.retain_left_ns = kNanosPerSecond,
               .clock = fc.clock(),
               .recorder = {.cycles = kCycles, .pages = pages}}),
          sup(reg, agg) {}
    void join(const char* prefix) {
      for (int i = 0; i < 6; ++i) {
        comps.push_back(std::make_unique<Instrumentation>(prefix + std::to_string(i),
                                                          task::SupervisionOptions{}, reg));
        comps.back()->init();
      }
      sup.step();
    }
    Registry<task::Message> reg;
    vigil::test::FakeClock fc;
    ComponentAggregator agg;
    ComponentDrainLoop sup;
    std::vector<std::unique_ptr<Instrumentation>> comps;
  };
  System huge(RingPages::Huge);
  System automatic(RingPages::Auto);
  System ordinary(RingPages::Ordinary);
  for (System* s : {&huge, &automatic, &ordinary}) {
    s->join("c");
    for (int k = 0; k < 5; ++k) {
      for (auto& comp : s->comps) comp->run([] {});
      s->sup.step();
    }
  }
  CHECK(huge.agg.rings_on_huge_pages() == 6);
  CHECK(huge.agg.ring_region_bytes() == 2 * kRegion);
  // Auto: the rings that joined once four (a region's worth) were in use.
  CHECK(automatic.agg.rings_on_huge_pages() == 2);
  CHECK(automatic.agg.ring_region_bytes() == kRegion);
  CHECK(ordinary.agg.rings_on_huge_pages() == 0);
  CHECK(ordinary.agg.ring_region_bytes() == 0);
  // Wherever its memory is, a ring records the same cycles.
  for (const System* s : {&huge, &automatic, &ordinary}) {
    const auto rec = s->agg.flight_record("c5");
    REQUIRE(rec.has_value());
    REQUIRE(rec->cycles.size() == 5);
    CHECK(rec->cycles.front().cycle == 1);
    CHECK(rec->cycles.back().cycle == 5);
  }
  // Records forgotten give their blocks back; components joining again take them, no new region.
  huge.comps.clear();
  huge.sup.step();
  huge.fc.advance(2 * kNanosPerSecond);
  huge.sup.step();
  CHECK(huge.agg.size() == 0);
  CHECK(huge.agg.rings_on_huge_pages() == 0);
  huge.join("d");
  CHECK(huge.agg.rings_on_huge_pages() == 6);
  CHECK(huge.agg.ring_region_bytes() == 2 * kRegion);
}

TEST_CASE("Stress: many components push while the supervisor drains and readers snapshot",
          "[supervisor][stress]") {
  // Run under TSan in CI: proves the pipeline has no data race.
  constexpr int kComponents = 8;
  constexpr int kCycles = 20000;
  // Also with streaming stores: their fence before the record's lock is released is what makes
  // the slots visible to the readers' copies.
  const RingStores stores = GENERATE(RingStores::Auto, RingStores::Streaming);
  Registry<task::Message> reg;
  ComponentAggregator agg({.recorder = {.stores = stores}});
  ComponentDrainLoop sup(reg, agg, {.period_ns = 200 * kNanosPerMicro});
  REQUIRE(sup.start().has_value());
  std::atomic<bool> done{false};
  std::atomic<int> snapshots{0};
  std::thread reader([&] {
    while (!done) {
      const auto all = agg.snapshot();
      for (const auto& s : all) {
        if (s.counters.cycles > kCycles) throw std::logic_error("impossible count");
      }
      ++snapshots;
      (void)sup.stats();
    }
  });
  std::vector<std::thread> producers;
  for (int c = 0; c < kComponents; ++c) {
    producers.emplace_back([&, c] {
      Instrumentation s("c" + std::to_string(c), {}, reg);
      s.init();
      for (int i = 0; i < kCycles; ++i) {
        s.run([] {});
        if (i % 1000 == 0) std::this_thread::yield();
      }
      // Leave while the supervisor runs.
    });
  }
  for (auto& t : producers) t.join();
  done = true;
  reader.join();
  sup.stop();
  const auto all = agg.snapshot();
  REQUIRE(all.size() == kComponents);
  for (const auto& s : all) {
    CHECK(s.counters.cycles == kCycles);
    CHECK_FALSE(s.alive);
    CHECK(s.samples + s.counters.dropped >= kCycles);
  }
  CHECK(snapshots > 0);
}

TEST_CASE("The aggregator keeps the latest real-time loss report, counts come from the samples",
          "[supervisor][aggregator]") {
  Registry<task::Message> reg;
  ComponentAggregator agg;
  ComponentDrainLoop sup(reg, agg);
  auto m = reg.join<16>("lossy");
  task::CycleSample s;
  s.counters.cycles = 7;
  s.counters.losses[static_cast<std::size_t>(platform::LossCause::Allocation)] = 3;
  REQUIRE(
      m.port()->try_push(task::Message{task::RealTimeLoss{7, platform::LossCause::Allocation, 2}}));
  REQUIRE(m.port()->try_push(task::Message{s}));
  sup.step();
  const auto snap = agg.find("lossy");
  REQUIRE(snap.has_value());
  REQUIRE(snap->has_loss);
  CHECK(snap->last_loss.cycle == 7);
  CHECK(snap->last_loss.cause == platform::LossCause::Allocation);
  CHECK(snap->last_loss.count == 2);
  CHECK(snap->counters.loss(platform::LossCause::Allocation) ==
        3);  // the sample's total, not the report's
}

TEST_CASE("The aggregator's percentiles keep the documented bound against exact percentiles",
          "[supervisor][aggregator][accuracy]") {
  // A known distribution of user times: two modes and a tail (50-62 us, ~200 us, a few ms), as a
  // component's cycle time looks; the record's compact histograms must report every percentile
  // as exact <= reported <= exact + exact / 32 (docs: relative error < 2^-5), and exactly what
  // a fixed RunningStats reports for the same samples.
  Registry<task::Message> reg;
  auto member = reg.join<1024>("known");
  ComponentAggregator agg({.warmup_ns = 0});
  ComponentDrainLoop sup(reg, agg);
  sup.step();
  std::vector<Nanos> user;
  RunningStats reference;
  std::uint64_t state = 12345;
  const auto next = [&] {  // a small LCG: the same numbers on every platform
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return state >> 33;
  };
  Nanos release = 1'000'000;
  for (std::uint64_t c = 1; c <= 20'000; ++c) {
    const std::uint64_t r = next() % 1000;
    const Nanos u = r < 900   ? 50'000 + static_cast<Nanos>(next() % 12'000)
                    : r < 995 ? 190'000 + static_cast<Nanos>(next() % 20'000)
                              : 1'000'000 + static_cast<Nanos>(next() % 4'000'000);
    task::CycleSample s;
    s.counters.cycles = c;
    s.release_ns = release;
    s.start_ns = release + 1'000;
    s.end_ns = s.start_ns + u;
    release += kNanosPerMilli;
    user.push_back(u);
    reference.add(u);
    REQUIRE(member.port()->try_push(task::Message{s}));
    if (c % 1000 == 0) sup.step();
  }
  const auto snap = agg.find("known");
  REQUIRE(snap.has_value());
  REQUIRE(snap->execution_ns.count == user.size());
  CHECK(snap->execution_ns == reference.summary());
  std::sort(user.begin(), user.end());
  const auto exact = [&](double q) {
    const auto rank = std::clamp<std::size_t>(
        static_cast<std::size_t>(std::ceil(q * static_cast<double>(user.size()))), 1, user.size());
    return user[rank - 1];
  };
  for (const auto& [q, got] :
       {std::pair{0.5, snap->execution_ns.p50}, std::pair{0.9, snap->execution_ns.p90},
        std::pair{0.99, snap->execution_ns.p99}, std::pair{0.999, snap->execution_ns.p999}}) {
    INFO("q = " << q << ", exact = " << exact(q) << ", reported = " << got);
    CHECK(got >= exact(q));
    CHECK(got - exact(q) <= exact(q) / 32);
  }
  // The histograms behind them stay small: the seen octaves only.
  agg.visit_distributions([](const ComponentDistributions& d) {
    CHECK(d.execution->histogram().heap_bytes() < sizeof(RunningStats::Histogram) / 2);
    CHECK(d.latency->histogram().heap_bytes() == 256);  // a constant 1 us: one chunk
  });
}

namespace {
// What two aggregators fed the same stream must agree on: the statistics, bit for bit.
void check_same_statistics(const ComponentSnapshot& got, const ComponentSnapshot& want) {
  CHECK(got.execution_ns == want.execution_ns);
  CHECK(got.latency_ns == want.latency_ns);
  CHECK(got.measured_period_ns == want.measured_period_ns);
  CHECK(got.overhead_ns == want.overhead_ns);
  CHECK(got.total_ns == want.total_ns);
  CHECK(got.samples == want.samples);
  CHECK(got.warmup_cycles == want.warmup_cycles);
}

// The aggregator without its on_batch(): the supervisor then hands it message by message (on()).
struct OneByOne {
  using Entry = bus::RegistryEntry<task::Message>;
  explicit OneByOne(ComponentAggregator& a) : agg(a) {}
  void on_join(const Entry& e) { agg.on_join(e); }
  void on_leave(const Entry& e) { agg.on_leave(e); }
  void begin(const Entry& e) { agg.begin(e); }
  void end(const Entry& e, const PortDrain& d) { agg.end(e, d); }
  void on_cycle(const DrainCycle& c) { agg.on_cycle(c); }
  template <class M>
  void on(const Entry& e, const M& m) {
    agg.on(e, m);
  }
  ComponentAggregator& agg;
};
}  // namespace

TEST_CASE("A batch of messages does what each message handed over in turn does",
          "[supervisor][aggregator]") {
  // on_batch() takes runs of common samples straight into the flight ring and leaves the rest to
  // the path of one message. Whatever the stream (gaps, overruns, totals-only samples, times a
  // slot keeps inexactly, clipped missed releases, loss reports waiting for their cycle, a
  // warm-up, a full ring), the ring, the counters and the statistics must be what on() of each
  // message in turn gives.
  std::mt19937_64 rng(GENERATE(11, 12, 13, 14));
  const std::size_t ring = GENERATE(std::size_t{16}, std::size_t{1024});
  // The batch's runs written through the caches and with streaming stores (RingStores): the same.
  const RingStores stores = GENERATE(RingStores::Cached, RingStores::Streaming);
  const AggregatorOptions options{.warmup_ns = 5 * kNanosPerMilli, .recorder = {.cycles = ring}};
  AggregatorOptions batch_options = options;
  batch_options.recorder.stores = stores;
  Registry<task::Message> reg_batch;
  Registry<task::Message> reg_one;
  ComponentAggregator batch_agg(batch_options);
  ComponentAggregator one_agg(options);
  ComponentDrainLoop batch(reg_batch, batch_agg);
  OneByOne one_handler(one_agg);
  DrainLoop<task::Message, OneByOne> one(reg_one, one_handler);
  auto member_batch = reg_batch.join<256>("c");
  auto member_one = reg_one.join<256>("c");
  std::uniform_int_distribution<Nanos> latency(-500, 80'000);
  std::uniform_int_distribution<Nanos> user(0, 400'000);
  std::uint64_t cycle = 0;
  task::Counters counters;
  Nanos release = kNanosPerSecond;
  std::size_t overruns = 0;
  std::size_t totals_only = 0;
  std::size_t losses = 0;
  for (int drain = 0; drain < 80; ++drain) {
    const auto n = static_cast<int>(rng() % 200);
    for (int i = 0; i < n; ++i) {
      const auto push = [&](const task::Message& m) {
        REQUIRE(member_batch.port()->try_push(m));
        REQUIRE(member_one.port()->try_push(m));
      };
      task::CycleSample s;
      if (rng() % 97 == 0 && cycle > 0) {
        s.totals_only = true;  // the latest cycle's counters again
        ++totals_only;
      } else {
        cycle += rng() % 50 == 0 ? 3 : 1;  // now and then a gap
        release += kNanosPerMilli;
        s.missed_before = rng() % 300 == 0 ? 70'000U : static_cast<std::uint32_t>(rng() % 2);
        s.release_ns = release;
        s.start_ns = release + latency(rng);
        s.end_ns = s.start_ns + (rng() % 400 == 0 ? 3 * kNanosPerSecond : user(rng));
        s.overhead_ns = rng() % 8 == 0 ? static_cast<Nanos>(100 + rng() % 900) : 0;
        s.overrun = rng() % 60 == 0;
        if (s.overrun) {
          ++overruns;
          ++counters.overruns;
        }
        counters.missed_cycles += s.missed_before;
        if (rng() % 150 == 0) {  // a loss reported before the sample of its cycle
          ++losses;
          ++counters.losses[0];
          push(task::Message{task::RealTimeLoss{.cycle = cycle, .count = 1}});
        }
      }
      counters.cycles = cycle;
      s.counters = counters;
      s.state = TaskState::Running;
      push(task::Message{s});
    }
    batch.step();
    one.step();
  }
  CHECK(overruns > 0);
  CHECK(totals_only > 0);
  CHECK(losses > 0);
  const auto a = one_agg.flight_record("c");
  const auto b = batch_agg.flight_record("c");
  REQUIRE(a.has_value());
  REQUIRE(b.has_value());
  REQUIRE(a->cycles.size() == ring);
  REQUIRE(b->cycles.size() == a->cycles.size());
  for (std::size_t i = 0; i < a->cycles.size(); ++i) {
    INFO("record " << i << ", cycle " << a->cycles[i].cycle);
    vigil::test::check_same(b->cycles[i], a->cycles[i]);
  }
  const auto sa = one_agg.find("c");
  const auto sb = batch_agg.find("c");
  REQUIRE(sa.has_value());
  REQUIRE(sb.has_value());
  CHECK(sa->counters.cycles == cycle);
  check_same_statistics(*sb, *sa);
  CHECK(sb->counters == sa->counters);
  CHECK(sb->state == sa->state);
  CHECK(sb->last.cycle() == sa->last.cycle());
  CHECK(sb->events == sa->events);
  CHECK(sb->has_loss == sa->has_loss);
}

TEST_CASE("The statistics are the same whether cycles are taken at once or in bulk from the ring",
          "[supervisor][aggregator]") {
  // The aggregator packs each drained cycle into the flight ring and takes the ring's pending
  // cycles into the statistics in bulk (at a threshold, before the ring would overwrite one,
  // and whenever someone reads). Without a ring it takes each cycle at once. Both must give the
  // same statistics, bit for bit: random times (a few beyond what a ring slot keeps exactly),
  // gaps, sampled overheads, a warm-up, drains of any size, reads at any time.
  std::mt19937_64 rng(GENERATE(1, 2, 3));
  struct Side {
    explicit Side(std::size_t ring)
        : agg({.warmup_ns = 3 * kNanosPerMilli, .recorder = {.cycles = ring}}),
          sup(reg, agg),
          member(reg.join<256>("c")) {}
    Registry<task::Message> reg;
    ComponentAggregator agg;
    ComponentDrainLoop sup;
    bus::Membership<task::Message, 256> member;
  };
  Side at_once(0);
  Side small_ring(16);
  Side default_ring(1024);
  std::array<Side*, 3> sides{&at_once, &small_ring, &default_ring};
  std::uniform_int_distribution<Nanos> latency(-500, 80'000);
  std::uniform_int_distribution<Nanos> user(0, 400'000);
  std::uint64_t cycle = 0;
  Nanos release = kNanosPerSecond;
  for (int drain = 0; drain < 60; ++drain) {
    const auto n = static_cast<int>(rng() % 257);  // up to a full port
    for (int i = 0; i < n; ++i) {
      cycle += rng() % 50 == 0 ? 3 : 1;  // now and then a gap
      release += kNanosPerMilli;
      task::CycleSample s;
      s.counters.cycles = cycle;
      s.release_ns = release;
      s.start_ns = release + latency(rng);
      s.end_ns = s.start_ns + (rng() % 500 == 0 ? 3 * kNanosPerSecond : user(rng));
      s.overhead_ns = rng() % 8 == 0 ? static_cast<Nanos>(100 + rng() % 900) : 0;
      s.state = TaskState::Running;
      for (Side* side : sides) REQUIRE(side->member.port()->try_push(task::Message{s}));
    }
    for (Side* side : sides) side->sup.step();
    if (rng() % 4 == 0) (void)small_ring.agg.find("c");  // a reader catches up in between
  }
  const auto a = at_once.agg.find("c");
  REQUIRE(a.has_value());
  CHECK(a->execution_ns.count > 5'000);
  for (Side* side : {&small_ring, &default_ring}) {
    const auto b = side->agg.find("c");
    REQUIRE(b.has_value());
    check_same_statistics(*b, *a);
  }
}

TEST_CASE("The statistics' catch-up gives the same results with either instruction set",
          "[supervisor][aggregator]") {
  // On x86-64 the catch-up is compiled for the base set and for LZCNT + BMI2, and the process
  // picks one from CPUID. The same stream through both must give the same statistics, bit for
  // bit: values across every octave the histograms cover (and below their exact range), gaps,
  // overheads, cycles a ring slot keeps inexactly.
  using Set = ComponentAggregator::InstructionSet;
  const Set chosen = ComponentAggregator::instruction_set();
  struct Restore {
    Set set;
    ~Restore() { (void)ComponentAggregator::set_instruction_set(set); }
  } restore{chosen};
  CHECK(std::string(ComponentAggregator::name(Set::Base)) == "base");
  CHECK(std::string(ComponentAggregator::name(Set::LzcntBmi2)) == "lzcnt+bmi2");
  // Each copy this build and CPU have is accepted and then reported; one that is not is refused
  // and changes nothing.
  std::vector<Set> copies;
  for (const Set set : {Set::Base, Set::LzcntBmi2}) {
    const Set before = ComponentAggregator::instruction_set();
    if (ComponentAggregator::set_instruction_set(set)) {
      copies.push_back(set);
      CHECK(ComponentAggregator::instruction_set() == set);
    } else {
      CHECK(ComponentAggregator::instruction_set() == before);
    }
  }
  REQUIRE(!copies.empty());
  CHECK(std::find(copies.begin(), copies.end(), chosen) != copies.end());
  if (copies.size() < 2) {
    WARN("this build and CPU have one catch-up only (" << ComponentAggregator::name(copies[0])
                                                       << "): nothing to compare it with");
    return;
  }
  CHECK(chosen == Set::LzcntBmi2);  // when both can run, the process starts with the faster
  std::mt19937_64 rng(GENERATE(1, 2));
  struct Side {
    explicit Side(Set s)
        : set(s), agg({.recorder = {.cycles = 256}}), sup(reg, agg), member(reg.join<256>("c")) {}
    Set set;
    Registry<task::Message> reg;
    ComponentAggregator agg;
    ComponentDrainLoop sup;
    bus::Membership<task::Message, 256> member;
  };
  Side base(Set::Base);
  Side bits(Set::LzcntBmi2);
  std::uint64_t cycle = 0;
  Nanos release = kNanosPerSecond;
  // A value of 2^k + a few bits, k from 0 to 35 (beyond the 2.1 s a ring slot keeps exactly).
  const auto any_octave = [&] {
    const int k = static_cast<int>(rng() % 36);
    return (Nanos{1} << k) + static_cast<Nanos>(rng() % (std::uint64_t{1} << k));
  };
  for (int drain = 0; drain < 40; ++drain) {
    const auto n = static_cast<int>(rng() % 257);
    for (int i = 0; i < n; ++i) {
      cycle += rng() % 50 == 0 ? 3 : 1;
      release += any_octave();
      task::CycleSample s;
      s.counters.cycles = cycle;
      s.release_ns = release;
      s.start_ns = release + (rng() % 3 == 0 ? static_cast<Nanos>(rng() % 64) : any_octave());
      s.end_ns = s.start_ns + any_octave();
      s.overhead_ns = rng() % 8 == 0 ? any_octave() : 0;
      s.state = TaskState::Running;
      for (Side* side : {&base, &bits}) REQUIRE(side->member.port()->try_push(task::Message{s}));
    }
    for (Side* side : {&base, &bits}) {
      REQUIRE(ComponentAggregator::set_instruction_set(side->set));
      side->sup.step();
    }
  }
  // Reading catches up what is still pending, with the set of each side.
  std::optional<ComponentSnapshot> a;
  std::optional<ComponentSnapshot> b;
  REQUIRE(ComponentAggregator::set_instruction_set(Set::Base));
  a = base.agg.find("c");
  REQUIRE(ComponentAggregator::set_instruction_set(Set::LzcntBmi2));
  b = bits.agg.find("c");
  REQUIRE(a.has_value());
  REQUIRE(b.has_value());
  CHECK(a->execution_ns.count > 2'000);
  check_same_statistics(*b, *a);
}

TEST_CASE("Rings stream when the drains sweep far more than the last-level cache, or when told to",
          "[supervisor][aggregator][recorder]") {
  using A = ComponentAggregator;
  constexpr std::size_t kMiB = std::size_t{1} << 20U;
  CHECK_FALSE(A::streams_rings(RingStores::Auto, 8 * kMiB, 32 * kMiB));
  CHECK_FALSE(A::streams_rings(RingStores::Auto, 65 * kMiB, 32 * kMiB));  // 1,000 components
  CHECK_FALSE(A::streams_rings(RingStores::Auto, 128 * kMiB, 32 * kMiB));
  CHECK(A::streams_rings(RingStores::Auto, 132 * kMiB, 32 * kMiB));
  CHECK(A::streams_rings(RingStores::Auto, 650 * kMiB, 32 * kMiB));  // 10,000 components
  CHECK_FALSE(A::streams_rings(RingStores::Auto, 1024 * kMiB, 0));   // cache unknown: never
  CHECK_FALSE(A::streams_rings(RingStores::Cached, 1024 * kMiB, 1));
  CHECK(A::streams_rings(RingStores::Streaming, 0, 32 * kMiB));
  // A few components' rings fit any cache: Auto writes through it; Streaming is kept.
  Registry<task::Message> reg;
  ComponentAggregator automatic;
  ComponentAggregator streaming({.recorder = {.stores = RingStores::Streaming}});
  ComponentDrainLoop a(reg, automatic);
  ComponentDrainLoop b(reg, streaming);
  auto member = reg.join<16>("c");
  a.step();
  b.step();
  CHECK_FALSE(automatic.streams_rings());
  CHECK(streaming.streams_rings());
}

namespace {
// The worst cycles of component `name`, by window.
std::array<WorstCycles, 4> worst_of(const ComponentAggregator& agg, std::string_view name) {
  std::array<WorstCycles, 4> out{};
  agg.visit_distributions([&](const ComponentDistributions& d) {
    if (d.name == name) {
      out = {d.execution_worst, d.total_worst, d.latency_worst, d.measured_period_worst};
    }
  });
  return out;
}
}  // namespace

TEST_CASE("The aggregator keeps the worst cycle of each distribution per window",
          "[supervisor][aggregator][exemplar]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {.overhead_sample_every = 0}, reg);
  Nanos work = 100;
  p.work = [&] { fc.advance(work); };
  ManualActivity act(p, {.name = "m", .period_ns = kNanosPerMilli, .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  ComponentAggregator agg({.warmup_ns = 0, .worst_window_ns = 100 * kNanosPerMilli});
  ComponentDrainLoop sup(reg, agg);
  // Window 1: cycles 1..100; cycle 37 works longest, cycle 52 wakes latest, and the period
  // ending at cycle 52 (from 51) is the longest.
  const auto run = [&](int from, int to, int long_work, int late) {
    for (int c = from; c <= to; ++c) {
      work = c == long_work ? 700 * kNanosPerMicro : 100 + c;
      fc.set(act.next_release() + (c == late ? 300 * kNanosPerMicro : 10));
      act.step();
      if (c % 10 == 0) sup.step();  // drains of 10 cycles, taken in runs
    }
    sup.step();
  };
  run(1, 100, 37, 52);
  auto w = worst_of(agg, "p");
  CHECK(w[0].previous.cycle == 0);
  CHECK(w[0].current.cycle == 37);
  CHECK(w[0].current.value_ns == 700 * kNanosPerMicro);
  CHECK(w[1].current.cycle == 37);  // total: execution plus the (zero) overhead
  CHECK(w[2].current.cycle == 52);
  CHECK(w[2].current.value_ns == 300 * kNanosPerMicro);
  CHECK(w[3].current.cycle == 52);
  CHECK(w[3].current.value_ns == kNanosPerMilli + 300 * kNanosPerMicro - 10);
  CHECK(w[2].current.start_ns > w[0].current.start_ns);

  // Window 2 (cycles 101..200, in runs that start in it): the first window becomes previous,
  // its worst cycles are this window's own even when smaller.
  run(101, 200, 150, 180);
  w = worst_of(agg, "p");
  CHECK(w[0].previous.cycle == 37);
  CHECK(w[0].current.cycle == 150);
  CHECK(w[2].previous.cycle == 52);
  CHECK(w[2].current.cycle == 180);

  // A cycle half a second late: the windows in between had no cycle, so nothing is previous.
  work = 100;
  fc.set(act.next_release() + 500 * kNanosPerMilli);
  act.step();
  sup.step();
  w = worst_of(agg, "p");
  CHECK(w[2].previous.cycle == 0);
  CHECK(w[2].current.cycle == 201);
  CHECK(w[2].current.value_ns == 500 * kNanosPerMilli);
}

TEST_CASE("The aggregator keeps no worst cycles when their window is 0",
          "[supervisor][aggregator][exemplar]") {
  Registry<task::Message> reg;
  vigil::test::FakeClock fc;
  vigil::test::Probe p("p", {.overhead_sample_every = 0}, reg);
  p.work = [&] { fc.advance(100); };
  ManualActivity act(p, {.name = "m", .period_ns = kNanosPerMilli, .clock = fc.clock()});
  REQUIRE(p.configure());
  REQUIRE(act.start(fc.now()));
  ComponentAggregator agg({.warmup_ns = 0, .worst_window_ns = 0});
  ComponentDrainLoop sup(reg, agg);
  for (int c = 0; c < 50; ++c) {
    fc.set(act.next_release() + 10);
    act.step();
  }
  sup.step();
  REQUIRE(agg.find("p")->execution_ns.count == 50);
  for (const WorstCycles& w : worst_of(agg, "p")) {
    CHECK(w.current.cycle == 0);
    CHECK(w.previous.cycle == 0);
  }
}
