// Linked with vigil::alloc_guard: the real-time side of a shared-memory port allocates nothing.
#include <catch2/catch.hpp>
#include <thread>

#include "shm_support.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/task/shm_messages.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace vigil::bus;

namespace {
class Ctl : public Task<Ctl> {
 public:
  explicit Ctl(Registry<task::Message>& registry)
      : Task("alloc", {.detectors = Detectors::Allocation}, registry) {}
  void on_update() {}
};
}  // namespace

#if defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("Allocation counting is unavailable under sanitizers", "[shm][alloc]") {
  WARN("skipped: sanitizers interpose malloc themselves");
  CHECK_FALSE(platform::allocation_counting_available());
}
#else
TEST_CASE("Cycles pushing to a shared-memory port allocate nothing, full ring or not",
          "[shm][alloc]") {
  REQUIRE(platform::allocation_counting_available());
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  Registry<task::Message> reg;
  bus::ShmOptions o;
  o.name = name;
  REQUIRE(place_in_shared_memory(reg, o).has_value());
  std::uint64_t allocations = ~std::uint64_t{0};
  std::uint64_t cycles = 0;
  std::uint64_t dropped = 0;
  std::thread component([&] {
    Ctl c(reg);
    ManualActivity act(c, {.name = "m", .period_ns = kNanosPerMilli});
    c.configure();
    act.start();
    act.step();  // the first cycle may touch lazily initialised state
    REQUIRE(c.port()->shm() != nullptr);
    const auto before = platform::thread_allocations();
    // No daemon drains it: after 256 cycles every push fails and goes to the mailbox.
    for (int i = 0; i < 100'000; ++i) act.step();
    allocations = platform::thread_allocations() - before;
    cycles = c.cycles();
    dropped = c.port()->dropped();
    act.stop();
  });
  component.join();
  CHECK(allocations == 0);
  CHECK(cycles == 100'001);
  CHECK(dropped > 99'000);
}
#endif
