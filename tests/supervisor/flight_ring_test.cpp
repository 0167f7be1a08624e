// The flight ring's 32-byte slots: what goes in comes out, to the nanosecond where it fits and
// to the microsecond (flagged) where it does not; nothing wraps silently.
#include <algorithm>
#include <array>
#include <bit>
#include <catch2/catch.hpp>
#include <cstdint>
#include <limits>
#include <new>
#include <random>
#include <vector>

#include "support/cycle_record.hpp"
#include "vigil/supervisor/flight_recorder.hpp"

using namespace vigil;
using namespace vigil::supervisor;
using vigil::test::check_same;

namespace {

CycleRecord record(std::uint64_t cycle, Nanos release, Nanos latency, Nanos user) {
  CycleRecord r;
  r.cycle = cycle;
  r.release_ns = release;
  r.start_ns = release + latency;
  r.end_ns = r.start_ns + user;
  r.overhead_ns = 140;
  r.missed_before = 3;
  r.flags = CycleRecord::kOverrun | CycleRecord::kWarmup;
  r.state = TaskState::Running;
  return r;
}

}  // namespace

TEST_CASE("A flight ring slot keeps a cycle exactly within +-2.1 s", "[supervisor][recorder]") {
  const Nanos big_release = std::int64_t{1} << 62;  // monotonic clocks count from boot, TSC high
  for (const CycleRecord& r :
       {record(1, 1'000'000, 2'000, 50'000), record(~std::uint64_t{0}, big_release, 0, 0),
        record(7, -5'000, -300, 1),  // a release after the start: a clock's calibration error
        record(9, 0, 0x7FFF'FFFF, 0x7FFF'FFFF), record(10, 0, -0x7FFF'FFFF, 0)}) {
    check_same(PackedCycle(r).unpack(), r);
    // The catch-up's read of an exact slot (every pending one) gives the same record.
    check_same(PackedCycle(r).unpack_exact(), r);
  }
  CycleRecord r = record(2, 10, 20, 30);
  r.overhead_ns = 0xFFFF'FFFF;
  r.missed_before = 0xFFFF;
  r.state = TaskState::Exception;
  r.flags = CycleRecord::kGap;
  check_same(PackedCycle(r).unpack(), r);
  check_same(PackedCycle(r).unpack_exact(), r);
}

TEST_CASE("A flight ring slot keeps longer times to the microsecond, flagged",
          "[supervisor][recorder]") {
  const CycleRecord r = record(5, 1'000'000'000, 3'000'123, 5'000'000'999LL);  // 5 s update
  const CycleRecord u = PackedCycle(r).unpack();
  CHECK((u.flags & CycleRecord::kCoarse) != 0);
  CHECK((u.flags & CycleRecord::kClipped) == 0);
  CHECK(u.release_ns == r.release_ns);
  CHECK(u.latency_ns() == 3'000'000);
  CHECK(u.execution_ns() == 5'000'000'000LL);
  CHECK(u.cycle == 5);

  const CycleRecord late = record(6, 0, -3'000'000'000LL, 100);  // negative, beyond 2.1 s
  const CycleRecord l = PackedCycle(late).unpack();
  CHECK((l.flags & CycleRecord::kCoarse) != 0);
  CHECK(l.latency_ns() == -3'000'000'000LL);
  CHECK(l.execution_ns() == 0);  // 100 ns in microseconds
}

TEST_CASE("A flight ring slot saturates what it cannot hold and says so",
          "[supervisor][recorder]") {
  CycleRecord r = record(1, 0, 100, 100);
  r.missed_before = 70'000;
  CycleRecord u = PackedCycle(r).unpack();
  CHECK(u.missed_before == 0xFFFF);
  CHECK((u.flags & CycleRecord::kClipped) != 0);
  CHECK(u.execution_ns() == 100);  // the rest stays exact

  r = record(1, 0, 100, 100);
  r.overhead_ns = Nanos{5} * kNanosPerSecond;
  u = PackedCycle(r).unpack();
  CHECK(u.overhead_ns == 0xFFFF'FFFF);
  CHECK((u.flags & CycleRecord::kClipped) != 0);

  r = record(1, 0, 100, std::numeric_limits<std::int32_t>::max() * Nanos{1000} * 2);  // 50 days
  u = PackedCycle(r).unpack();
  CHECK((u.flags & (CycleRecord::kClipped | CycleRecord::kCoarse)) ==
        (CycleRecord::kClipped | CycleRecord::kCoarse));
  CHECK(u.execution_ns() == Nanos{0x7FFF'FFFF} * 1000);

  // Flags a caller passes in are recomputed, not trusted.
  r = record(1, 0, 100, 100);
  r.flags = CycleRecord::kClipped | CycleRecord::kCoarse;
  u = PackedCycle(r).unpack();
  CHECK(u.flags == 0);
  CHECK(u.execution_ns() == 100);
}

TEST_CASE("A flight ring keeps the newest cycles, oldest first", "[supervisor][recorder]") {
  FlightRing ring(4);
  CHECK(ring.empty());
  CHECK(ring.capacity() == 4);
  for (std::uint64_t c = 1; c <= 6; ++c) ring.push(record(c, Nanos(c) * 1'000'000, 1'000, 2'000));
  CHECK(ring.size() == 4);
  CHECK(ring.back().cycle == 6);
  const auto cycles = ring.ordered();
  REQUIRE(cycles.size() == 4);
  for (std::size_t i = 0; i < 4; ++i)
    check_same(cycles[i], record(3 + i, Nanos(3 + i) * 1'000'000, 1'000, 2'000));

  FlightRing none(0);
  none.push(record(1, 0, 0, 0));
  CHECK(none.empty());
  CHECK(none.next_slot() == nullptr);
  CHECK(none.ordered().empty());
}

TEST_CASE("A flight ring hands out its pending cycles once, oldest first, across wrap-around",
          "[supervisor][recorder]") {
  FlightRing ring(4);
  std::vector<std::uint64_t> taken;
  const auto take = [&] {
    ring.take_pending([&](const CycleRecord& r) { taken.push_back(r.cycle); });
  };
  ring.push(record(1, 1'000'000, 1'000, 2'000));  // not pending
  ring.push_pending(record(2, 2'000'000, 1'000, 2'000));
  ring.push_pending(record(3, 3'000'000, 1'000, 2'000));
  CHECK(ring.pending() == 2);
  take();
  CHECK(taken == std::vector<std::uint64_t>{2, 3});
  CHECK(ring.pending() == 0);
  take();  // nothing twice
  CHECK(taken.size() == 2);
  taken.clear();
  for (std::uint64_t c = 4; c <= 7; ++c) ring.push_pending(record(c, Nanos(c) * 1'000'000, 1, 2));
  CHECK(ring.pending() == 4);  // the whole ring, wrapped: slots 3, 0, 1, 2
  take();
  CHECK(taken == std::vector<std::uint64_t>{4, 5, 6, 7});
  CHECK(ring.ordered().front().cycle == 4);
}

TEST_CASE("A flight ring hands out at most the asked number of pending cycles, the oldest",
          "[supervisor][recorder]") {
  FlightRing ring(5);
  std::vector<std::uint64_t> taken;
  const auto take = [&](std::size_t max) {
    return ring.take_pending(max, [&](const CycleRecord& r) { taken.push_back(r.cycle); });
  };
  ring.push(record(1, 1'000'000, 1'000, 2'000));  // not pending
  ring.push(record(2, 2'000'000, 1'000, 2'000));
  ring.push(record(3, 3'000'000, 1'000, 2'000));
  // Five pending cycles, their slots wrapping past the ring's end: 3, 4, 0, 1, 2.
  for (std::uint64_t c = 4; c <= 8; ++c) ring.push_pending(record(c, Nanos(c) * 1'000'000, 1, 2));
  REQUIRE(ring.pending() == 5);
  CHECK(take(2) == 2);
  CHECK(taken == std::vector<std::uint64_t>{4, 5});
  CHECK(ring.pending() == 3);
  CHECK(take(0) == 0);  // none asked, none taken
  CHECK(ring.pending() == 3);
  CHECK(take(2) == 2);  // across the wrap
  CHECK(taken == std::vector<std::uint64_t>{4, 5, 6, 7});
  CHECK(take(64) == 1);  // more asked than pending: what there is
  CHECK(taken == std::vector<std::uint64_t>{4, 5, 6, 7, 8});
  CHECK(ring.pending() == 0);
  CHECK(take(64) == 0);
  // Taking leaves the records in the ring, newest last.
  CHECK(ring.size() == 5);
  CHECK(ring.back().cycle == 8);
  ring.push_pending(record(9, 9'000'000, 1, 2));
  CHECK(take(1) == 1);
  CHECK(taken.back() == 9);
}

TEST_CASE("A slot written with streaming stores is the slot constructed in place",
          "[supervisor][recorder]") {
  // PackedCycle::stream() writes the slot as four words where the CPU streams: byte for byte
  // what the constructor writes, whatever the fields' values.
  std::mt19937_64 rng(7);
  for (int i = 0; i < 1000; ++i) {
    const std::uint64_t cycle = rng();
    const auto release = static_cast<Nanos>(rng());
    const Nanos latency = static_cast<std::int32_t>(rng());
    const Nanos user = static_cast<std::int32_t>(rng());
    const Nanos overhead = static_cast<Nanos>(rng() & 0xFFFF'FFFFU);
    const auto missed = static_cast<std::uint32_t>(rng() & 0xFFFFU);
    const auto flags = static_cast<std::uint8_t>(rng() & 7U);
    const auto state = static_cast<TaskState>(rng() % 7);
    alignas(64) std::array<unsigned char, sizeof(PackedCycle)> streamed{};
    alignas(64) std::array<unsigned char, sizeof(PackedCycle)> constructed{};
    PackedCycle::stream(streamed.data(), cycle, release, latency, user, overhead, missed, flags,
                        state);
    PackedCycle::fence_streams();
    ::new (static_cast<void*>(constructed.data())) PackedCycle(
        PackedCycle::Exact{}, cycle, release, latency, user, overhead, missed, flags, state);
    INFO("case " << i);
    REQUIRE(streamed == constructed);
    const CycleRecord r = std::bit_cast<PackedCycle>(streamed).unpack();
    CHECK(r.cycle == cycle);
    CHECK(r.start_ns - r.release_ns == latency);
    CHECK(r.end_ns - r.start_ns == user);
    CHECK(r.state == state);
  }
}

TEST_CASE("A flight ring slot says which cycles it keeps exactly", "[supervisor][recorder]") {
  CHECK(PackedCycle::packs_exactly(record(1, 0, 2'147'483'647, 2'147'483'647)));
  CHECK_FALSE(PackedCycle::packs_exactly(record(1, 0, 2'147'483'648, 1)));
  CHECK_FALSE(PackedCycle::packs_exactly(record(1, 0, 1, -2'147'483'648)));
  CycleRecord r = record(1, 0, 1, 1);
  r.overhead_ns = -1;
  CHECK_FALSE(PackedCycle::packs_exactly(r));
  r.overhead_ns = 0x1'0000'0000LL;
  CHECK_FALSE(PackedCycle::packs_exactly(r));
  r.overhead_ns = 0;
  r.missed_before = 70'000;
  CHECK_FALSE(PackedCycle::packs_exactly(r));
  CHECK(PackedCycle::packs_exactly(record(1, 0, -2'147'483'647, -2'147'483'647)));
  CHECK_FALSE(PackedCycle::packs_exactly(record(1, 0, -2'147'483'648, 1)));
  // The checks cannot overflow: the extremes of a 64-bit time are refused, not wrapped.
  constexpr Nanos kMin = std::numeric_limits<Nanos>::min();
  constexpr Nanos kMax = std::numeric_limits<Nanos>::max();
  CHECK_FALSE(PackedCycle::fits_exactly(kMax, 0, 0, 0));
  CHECK_FALSE(PackedCycle::fits_exactly(kMin, 0, 0, 0));
  CHECK_FALSE(PackedCycle::fits_exactly(0, kMin, 0, 0));
  CHECK_FALSE(PackedCycle::fits_exactly(0, 0, kMin, 0));
  CHECK(PackedCycle::fits_exactly(0, 0, 0xFFFF'FFFFLL, 0xFFFFU));
  // What packs_exactly accepts comes back unchanged, what it refuses does not.
  for (const CycleRecord& c : {record(9, 5, -7, 2'000'000'000), record(9, 5, 3'000'000'000, 1)}) {
    const CycleRecord back = PackedCycle(c).unpack();
    const bool same = back.start_ns == c.start_ns && back.end_ns == c.end_ns;
    CHECK(same == PackedCycle::packs_exactly(c));
  }
}

TEST_CASE("Cycles pushed in runs from their exact parts read back as the same cycles pushed whole",
          "[supervisor][recorder]") {
  // The supervisor's common case packs runs of slots from samples' parts; a reader must not tell
  // them from records pushed whole (every field, each flag, each state, the extremes that fit),
  // whatever the runs' lengths and wherever they wrap.
  FlightRing whole(8);
  FlightRing parts(8);
  std::vector<CycleRecord> pushed;
  for (std::uint64_t c = 1; c <= 40; ++c) {
    CycleRecord r = record(c, static_cast<Nanos>(c) * 1'000'000 - 5'000,
                           c % 3 == 0 ? -2'147'483'647 : static_cast<Nanos>(c) * 17,
                           c % 4 == 0 ? 2'147'483'647 : static_cast<Nanos>(c) * 1'001);
    r.overhead_ns = c % 5 == 0 ? 0xFFFF'FFFFLL : static_cast<Nanos>(c);
    r.missed_before = c % 6 == 0 ? 0xFFFFU : static_cast<std::uint32_t>(c);
    r.flags = static_cast<std::uint8_t>(c % 8);  // kOverrun, kGap, kWarmup in every combination
    r.state = static_cast<TaskState>(c % 5);     // PreOperational .. FatalError
    REQUIRE(PackedCycle::packs_exactly(r));
    pushed.push_back(r);
  }
  std::size_t at = 0;
  std::size_t run = 1;
  while (at < pushed.size()) {
    // A run of 1 .. 5 cycles, or fewer if the ring has no more room.
    const std::size_t room = parts.capacity() - parts.pending();
    const std::size_t want = std::min({run, pushed.size() - at, room});
    std::size_t calls = 0;
    const std::size_t n = parts.push_pending_while([&](void* slot) {
      if (calls == want) return false;  // ends the run, writing nothing
      const CycleRecord& r = pushed[at + calls++];
      ::new (slot) PackedCycle(PackedCycle::Exact{}, r.cycle, r.release_ns, r.latency_ns(),
                               r.execution_ns(), r.overhead_ns, r.missed_before, r.flags, r.state);
      return true;
    });
    REQUIRE(n == want);
    for (std::size_t i = 0; i < n; ++i) whole.push_pending(pushed[at + i]);
    at += n;
    CHECK(parts.pending() == whole.pending());
    CHECK(parts.size() == whole.size());
    if (parts.pending() == parts.capacity()) {
      // Full: a run pushes nothing, without asking for a slot.
      CHECK(parts.push_pending_while([](void*) {
        FAIL("asked to pack into a full ring");
        return true;
      }) == 0);
      std::vector<std::uint64_t> a;
      std::vector<std::uint64_t> b;
      whole.take_pending([&](const CycleRecord& r) { a.push_back(r.cycle); });
      parts.take_pending([&](const CycleRecord& r) { b.push_back(r.cycle); });
      CHECK(a == b);
    }
    run = run % 5 + 1;
  }
  const auto a = whole.ordered();
  const auto b = parts.ordered();
  REQUIRE(a.size() == 8);
  REQUIRE(b.size() == 8);
  for (std::size_t i = 0; i < a.size(); ++i) {
    const CycleRecord& want = pushed[pushed.size() - 8 + i];
    for (const CycleRecord* got : {&a[i], &b[i]}) check_same(*got, want);
  }
  FlightRing none(0);
  CHECK_FALSE(none.has_room_pending());
  CHECK(none.push_pending_while([](void*) {
    FAIL("asked to pack into a ring without slots");
    return true;
  }) == 0);
  CHECK(none.size() == 0);
}
