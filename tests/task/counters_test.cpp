#include "vigil/task/counters.hpp"

#include <catch2/catch.hpp>
#include <type_traits>

using vigil::platform::LossCause;
using vigil::task::Counters;

namespace {
Counters sample(std::uint64_t base) {
  Counters c;
  c.cycles = base * 10;
  c.overruns = base;
  c.missed_cycles = base + 1;
  c.losses[static_cast<std::size_t>(LossCause::Allocation)] = base + 2;
  c.losses[static_cast<std::size_t>(LossCause::Blocking)] = base + 3;
  c.exceptions = base + 4;
  c.dropped = base + 5;
  return c;
}
}  // namespace

TEST_CASE("Counters are trivially copyable and list every member once", "[task][counters]") {
  STATIC_REQUIRE(std::is_trivially_copyable_v<Counters>);
  STATIC_REQUIRE(Counters::kScalars.size() == 5);
  STATIC_REQUIRE(sizeof(Counters) == (5 + vigil::task::kLossCauses) * sizeof(std::uint64_t));
}

TEST_CASE("Counters::merge keeps the larger of each counter", "[task][counters]") {
  Counters a = sample(5);
  Counters b = sample(3);
  b.dropped = 100;                                                // larger in b only
  b.losses[static_cast<std::size_t>(LossCause::MajorFault)] = 7;  // a has 0
  a.merge(b);
  CHECK(a.cycles == 50);
  CHECK(a.overruns == 5);
  CHECK(a.missed_cycles == 6);
  CHECK(a.loss(LossCause::Allocation) == 7);
  CHECK(a.loss(LossCause::Blocking) == 8);
  CHECK(a.loss(LossCause::MajorFault) == 7);
  CHECK(a.exceptions == 9);
  CHECK(a.dropped == 100);
  // Merging an older copy (a late report) never moves a counter back.
  const Counters before = a;
  a.merge(sample(1));
  CHECK(a == before);
}

TEST_CASE("Counters::since is the per-counter difference, clamped at 0", "[task][counters]") {
  const Counters now = sample(8);
  const Counters then = sample(5);
  const Counters d = now.since(then);
  CHECK(d.cycles == 30);
  CHECK(d.overruns == 3);
  CHECK(d.missed_cycles == 3);
  CHECK(d.loss(LossCause::Allocation) == 3);
  CHECK(d.loss(LossCause::Blocking) == 3);
  CHECK(d.loss(LossCause::MinorFault) == 0);
  CHECK(d.exceptions == 3);
  CHECK(d.dropped == 3);
  CHECK(d.total_losses() == 6);
  // A counter below its earlier value counts 0 rather than wrapping around.
  const Counters back = then.since(now);
  CHECK(back == Counters{});
  CHECK(now.since(Counters{}) == now);
}
