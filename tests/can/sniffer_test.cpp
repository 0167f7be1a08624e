#include "vigil/can/sniffer.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <map>
#include <thread>
#include <vector>

#include "can_test_support.hpp"
#include "vigil/platform/rt_loss.hpp"

using namespace vigil::can;
using vigil::kNanosPerMilli;
using vigil::Nanos;
using vigil::can::test::drain_records;
using vigil::can::test::frame;

TEST_CASE("Sniffer counts every frame exactly while its port drops records", "[can][sniffer]") {
  CanRegistry registry;
  Sniffer<16> sniffer(registry, "bus0");
  for (int i = 0; i < 1000; ++i) {
    const Nanos t = i * kNanosPerMilli;
    sniffer.on_read(frame(0x181 + static_cast<std::uint32_t>(i % 4), t), t - 5000, t);
  }
  sniffer.on_write(frame(0x601, 2 * vigil::kNanosPerSecond), 0, 2 * vigil::kNanosPerSecond);

  const SnifferTotals t = sniffer.totals();
  CHECK(t.frames == 1001);
  CHECK(t.rx == 1000);
  CHECK(t.tx == 1);
  CHECK(t.accepted == 1001);
  CHECK(t.rejected == 0);
  CHECK(t.untracked_ids == 0);
  CHECK(t.dropped == 1001 - 16);  // the port kept the first 16

  std::map<std::uint32_t, IdEntry> ids;
  for (const IdEntry& e : sniffer.ids()) ids[e.id] = e;
  REQUIRE(ids.size() == 5);
  for (std::uint32_t id = 0x181; id <= 0x184; ++id) {
    CHECK(ids[id].frames == 250);
    CHECK(ids[id].direction == Direction::Rx);
    CHECK(ids[id].first_ns == (id - 0x181) * kNanosPerMilli);
    CHECK(ids[id].last_ns == (996 + id - 0x181) * kNanosPerMilli);
  }
  CHECK(ids[0x601].frames == 1);
  CHECK(ids[0x601].direction == Direction::Tx);

  const auto records = drain_records(registry);
  REQUIRE(records.size() == 16);
  // The RT side measured each gap from its table: exact, whatever was dropped before.
  CHECK(records[0].id_gap_ns == -1);
  CHECK(records[0].id_frames == 1);
  CHECK(records[4].id == 0x181);
  CHECK(records[4].id_gap_ns == 4 * kNanosPerMilli);
  CHECK(records[4].id_frames == 2);
  CHECK(records[4].node_gap_ns == 4 * kNanosPerMilli);  // identity mapping: node = id
  CHECK(records[4].io_ns == 5000);
  CHECK(records[4].data[0] == 0x01);
}

TEST_CASE("Sniffer times a frame by its receive timestamp, not by the read that found it",
          "[can][sniffer]") {
  CanRegistry registry;
  Sniffer<16> sniffer(registry, "bus0");
  // Three frames arrive 10 ms apart; a late reader gets to the last two together, 30 ms on.
  sniffer.on_read(frame(0x181), 990'000, 1'000'000, 1'000'000);
  sniffer.on_read(frame(0x181), 40'000'000, 40'002'000, 11'000'000);
  sniffer.on_read(frame(0x181), 40'002'000, 40'003'000, 21'000'000);
  const std::vector<IdEntry> ids = sniffer.ids();
  REQUIRE(ids.size() == 1);
  CHECK(ids[0].first_ns == 1'000'000);
  CHECK(ids[0].last_ns == 21'000'000);  // not 40.003 ms: the frame's time is its arrival
  const auto records = drain_records(registry);
  REQUIRE(records.size() == 3);
  CHECK(records[1].time_ns == 11'000'000);
  CHECK(records[1].io_ns == 2000);                     // the read call's own time
  CHECK(records[1].id_gap_ns == 10 * kNanosPerMilli);  // the bus's gap, not the reader's
  CHECK(records[2].id_gap_ns == 10 * kNanosPerMilli);
}

TEST_CASE("Sniffer tracks nodes through its mapping", "[can][sniffer]") {
  CanRegistry registry;
  Sniffer<64> sniffer(registry, "bus0", {.node_map = NodeMap::canopen()});
  // Node 11: TPDO1 and heartbeat; node 12: TPDO1.
  sniffer.on_read(frame(0x18B, 1000), 1000, 1000);
  sniffer.on_read(frame(0x70B, 3000), 3000, 3000);
  sniffer.on_read(frame(0x18C, 4000), 4000, 4000);
  sniffer.on_read(frame(0x18B, 10000), 10000, 10000);
  std::map<std::uint32_t, NodeEntry> nodes;
  for (const NodeEntry& e : sniffer.nodes()) nodes[e.node] = e;
  REQUIRE(nodes.size() == 2);
  CHECK(nodes[11].frames == 3);
  CHECK(nodes[11].first_ns == 1000);
  CHECK(nodes[11].last_ns == 10000);
  CHECK(nodes[12].frames == 1);
  const auto records = drain_records(registry);
  REQUIRE(records.size() == 4);
  CHECK(records[1].node == 11);
  CHECK(records[1].function == 14);
  CHECK(records[1].id_gap_ns == -1);      // first heartbeat
  CHECK(records[1].node_gap_ns == 2000);  // but not the node's first frame
  CHECK(records[3].id_gap_ns == 9000);
  CHECK(records[3].node_gap_ns == 7000);
}

TEST_CASE("Sniffer's table is fixed: overflow is counted exactly, never blocks", "[can][sniffer]") {
  CanRegistry registry;
  Sniffer<8> sniffer(registry, "bus0", {.max_ids = 4, .max_nodes = 2});
  REQUIRE(sniffer.state()->max_ids() == 4);
  for (int round = 0; round < 3; ++round) {
    for (std::uint32_t id = 1; id <= 10; ++id) sniffer.on_read(frame(id, round), round, round);
  }
  const SnifferTotals t = sniffer.totals();
  CHECK(t.frames == 30);
  CHECK(t.accepted == 30);
  // Ids 1-4 took the 4 places; 6 ids x 3 frames had none.
  CHECK(t.untracked_ids == 18);
  CHECK(t.untracked_nodes == 24);  // nodes 1, 2 tracked (identity mapping)
  const auto ids = sniffer.ids();
  REQUIRE(ids.size() == 4);
  for (const IdEntry& e : ids) {
    CHECK(e.id <= 4);
    CHECK(e.frames == 3);
  }
  // A record is still pushed for untracked frames (timing is not lost), without an id count.
  const auto records = drain_records(registry);
  REQUIRE(records.size() == 8);
  CHECK(records[4].id == 5);
  CHECK(records[4].id_frames == 0);
  CHECK(records[4].id_gap_ns == -1);
}

TEST_CASE("TrackTable: power-of-two slots, bounded probes, insert-only", "[can][sniffer]") {
  detail::TrackTable<detail::NodeCounter> table(100);
  CHECK(table.slot_count() == 512);  // >= 4 x 100
  CHECK(table.max_entries() == 100);
  int inits = 0;
  const auto init = [&](detail::NodeCounter&) noexcept { ++inits; };
  for (std::uint32_t k = 0; k < 100; ++k) {
    const auto [slot, inserted] = table.find_or_insert(detail::node_key(0, k, false), init);
    REQUIRE(slot != nullptr);
    CHECK(inserted);
  }
  CHECK(table.size() == 100);
  const auto again = table.find_or_insert(detail::node_key(0, 7, false), init);
  CHECK(again.first != nullptr);
  CHECK_FALSE(again.second);
  CHECK(table.find_or_insert(detail::node_key(0, 1000, false), init).first == nullptr);  // full
  CHECK(inits == 100);
  std::size_t seen = 0;
  table.for_each([&](std::uint64_t, const detail::NodeCounter&) { ++seen; });
  CHECK(seen == 100);
  detail::TrackTable<detail::NodeCounter> none(0);
  CHECK(none.find_or_insert(detail::node_key(0, 1, false), init).first == nullptr);
}

TEST_CASE("Sniffer applies its filter before counting", "[can][sniffer][filter]") {
  CanRegistry registry;
  Sniffer<64> sniffer(registry, "bus0");
  REQUIRE(sniffer.set_filter(match::ids({0x181})).has_value());
  CHECK(sniffer.filter_text() == "ids(0x181)");
  for (int i = 0; i < 10; ++i) {
    sniffer.on_read(frame(0x181, i), i, i);
    sniffer.on_read(frame(0x182, i), i, i);
  }
  SnifferTotals t = sniffer.totals();
  CHECK(t.frames == 20);
  CHECK(t.accepted == 10);
  CHECK(t.rejected == 10);
  REQUIRE(sniffer.ids().size() == 1);
  CHECK(drain_records(registry).size() == 10);

  // A filter that does not compile leaves the current one in place.
  CHECK_FALSE(sniffer.set_filter(match::id_range(5, 1)).has_value());
  CHECK(sniffer.filter_text() == "ids(0x181)");
  sniffer.clear_filter();
  sniffer.on_read(frame(0x182, 20), 20, 20);
  t = sniffer.totals();
  CHECK(t.accepted == 11);
  CHECK(t.filter_changes == 2);
  CHECK(sniffer.state()->retired() == 0);  // nothing in flight: freed at once
}

TEST_CASE("Sniffer counts error frames apart", "[can][sniffer]") {
  CanRegistry registry;
  Sniffer<8> sniffer(registry, "bus0");
  sniffer.on_read(Frame::error_frame(0x4, {0, 0x10}), 0, 0);
  sniffer.on_read(frame(0x100, 1), 1, 1);
  const SnifferTotals t = sniffer.totals();
  CHECK(t.frames == 2);
  CHECK(t.error_frames == 1);
  CHECK(t.accepted == 1);
  // Error frames are counted per error class in the id table, with no node; their record
  // (flagged `error`, for the CAN supervisor's controller-state decoding) is pushed too.
  const auto ids = sniffer.ids();
  REQUIRE(ids.size() == 2);
  const auto err = std::find_if(ids.begin(), ids.end(), [](const IdEntry& e) { return e.error; });
  REQUIRE(err != ids.end());
  CHECK(err->id == 0x4);
  CHECK(err->node == vigil::can::kNoNode);
  CHECK(err->frames == 1);
  const auto records = drain_records(registry);
  REQUIRE(records.size() == 2);
  CHECK(records[0].error);
  CHECK(records[0].id == 0x4);
  CHECK(records[0].node == vigil::can::kNoNode);
  CHECK(records[0].data[1] == 0x10);
  CHECK_FALSE(records[1].error);
}

TEST_CASE("Sniffer state outlives the sniffer in its registry", "[can][sniffer]") {
  CanRegistry registry;
  std::uint32_t id = 0;
  {
    Sniffer<8> sniffer(registry, "bus0");
    id = sniffer.port_id();
    sniffer.on_read(frame(0x100, 1), 1, 1);
  }
  const auto state = registry.find(id);
  REQUIRE(state != nullptr);
  CHECK(state->totals().frames == 1);
  registry.release(id);
  CHECK(registry.find(id) == nullptr);
}

TEST_CASE("Filter replaced at run time while the I/O thread calls on_read",
          "[can][sniffer][filter][threads]") {
  CanRegistry registry;
  Sniffer<1024> sniffer(registry, "bus0");
  constexpr int kFrames = 200'000;
  std::atomic<bool> started{false};
  std::atomic<bool> done{false};
  std::thread io([&] {
    started.store(true, std::memory_order_release);
    for (int i = 0; i < kFrames; ++i) {
      const auto id = static_cast<std::uint32_t>(0x100 + (i % 8));
      sniffer.on_read(frame(id, i), i, i);
    }
    done.store(true, std::memory_order_release);
  });
  while (!started.load(std::memory_order_acquire)) std::this_thread::yield();
  int changes = 0;
  // Alternate between filters of different sizes (and accept-all) while frames flow.
  while (!done.load(std::memory_order_acquire) || changes < 100) {
    switch (changes % 3) {
      case 0:
        REQUIRE(sniffer.set_filter(match::ids({0x100, 0x101})).has_value());
        break;
      case 1: {
        std::vector<FilterExpr> parts;
        for (std::uint32_t k = 0; k < 50; ++k) parts.push_back(match::id_range(k, k + 1));
        REQUIRE(sniffer.set_filter(match::any_of(parts) || match::nodes({0x107})).has_value());
        break;
      }
      default:
        sniffer.clear_filter();
        break;
    }
    ++changes;
    static_cast<void>(sniffer.reclaim());
    drain_records(registry);  // plays the supervisor: the port is SPSC, one consumer
  }
  io.join();
  const SnifferTotals t = sniffer.totals();
  CHECK(t.frames == kFrames);
  CHECK(t.accepted + t.rejected == kFrames);
  CHECK(t.filter_changes == static_cast<std::uint64_t>(changes));
  std::uint64_t counted = 0;
  for (const IdEntry& e : sniffer.ids()) counted += e.frames;
  CHECK(counted == t.accepted);
  // The I/O thread is idle: every replaced filter can go now.
  static_cast<void>(sniffer.reclaim());
  CHECK(sniffer.state()->retired() == 0);
}

#if defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("Sniffer's on_read and on_write do not allocate", "[can][sniffer][alloc]") {
  WARN("skipped: the allocation guard is disabled under sanitizers");
}
#else
TEST_CASE("Sniffer's on_read and on_write do not allocate", "[can][sniffer][alloc]") {
  REQUIRE(vigil::platform::allocation_counting_available());
  CanRegistry registry;
  Sniffer<16> sniffer(registry, "bus0", {.max_ids = 64, .node_map = NodeMap::j1939()});
  REQUIRE(sniffer.set_filter(match::extended() && !match::ids({0x18FEF121})).has_value());
  const auto before = vigil::platform::thread_allocations();
  for (int i = 0; i < 10'000; ++i) {
    Frame f = Frame::classic(0x18FE0000U + static_cast<std::uint32_t>(i % 100), {1, 2, 3},
                             IdFormat::Extended);
    f.timestamp = i;
    sniffer.on_read(f, i, i);  // new ids, table overflow, port full: all without allocating
    sniffer.on_write(f, i, i);
  }
  const auto after = vigil::platform::thread_allocations();
  CHECK(after == before);
  CHECK(sniffer.totals().frames == 20'000);
  CHECK(sniffer.totals().untracked_ids > 0);
  CHECK(sniffer.totals().dropped > 0);
}
#endif
