// Linked with vigil::alloc_guard: 1,000,000 log calls allocate nothing on the logging thread,
// with the supervisor draining and the service formatting concurrently.
#include <catch2/catch.hpp>
#include <memory>
#include <string>
#include <thread>

#include "vigil/exec/manual_activity.hpp"
#include "vigil/log/log.hpp"
#include "vigil/log/service.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;

namespace {

enum class Phase : std::uint8_t { Idle, Moving };
[[maybe_unused]] const char* to_string(Phase p) { return p == Phase::Idle ? "idle" : "moving"; }

class Chatty : public Task<Chatty> {
 public:
  explicit Chatty(Registry<task::Message>& reg)
      : Task("log_chatty", {.detectors = Detectors::Allocation}, reg) {}
  void on_update() {
    ++n_;
    VIGIL_LOG_INFO("cycle {} of {}: {:.3f}", n_, 1'000'000, 0.5 * static_cast<double>(n_));
    if (n_ % 1000 == 0) {
      VIGIL_LOG_WARN("{} {} {}", name_, Phase::Moving, std::string_view("a string view"));
    }
    VIGIL_LOG_DEBUG("filtered at run time {}", n_);  // the default level is Info
  }

 private:
  std::uint64_t n_ = 0;
  std::string name_ = std::string(40, 'n');  // longer than the bound: truncated, not allocated
};

}  // namespace

#if defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("Allocation counting is unavailable under sanitizers", "[log][alloc]") {
  WARN("skipped: sanitizers interpose malloc themselves");
  CHECK_FALSE(platform::allocation_counting_available());
}
#else
TEST_CASE("1,000,000 log calls allocate nothing on the logging thread", "[log][alloc]") {
  REQUIRE(platform::allocation_counting_available());
  Registry<task::Message> reg;
  supervisor::ComponentAggregator agg;
  log::LogService service({.rate_limit = 100});
  auto tail = std::make_shared<log::TailSink>(4);
  service.add_sink(tail);
  agg.set_log_consumer(&service);
  supervisor::ComponentDrainLoop sup(reg, agg, {.period_ns = kNanosPerMilli});
  REQUIRE(sup.start().has_value());
  std::uint64_t allocations = ~std::uint64_t{0};
  std::uint64_t pushed = 0, dropped = 0;
  std::thread component([&] {
    Chatty c(reg);
    ManualActivity act(c, {.name = "m"});
    c.configure();
    act.start();
    act.step();  // the first cycle may touch lazily initialised state
    const auto before = platform::thread_allocations();
    for (int i = 0; i < 999'999; ++i) act.step();
    allocations = platform::thread_allocations() - before;
    act.stop();
    pushed = c.cycles();
    dropped = log::dropped("log_chatty");
  });
  component.join();
  sup.stop();
  agg.set_log_consumer(nullptr);
  service.flush();
  CHECK(allocations == 0);
  CHECK(pushed == 1'000'000);
  const auto s = agg.find("log_chatty");
  REQUIRE(s.has_value());
  CHECK(s->counters.losses[static_cast<int>(platform::LossCause::Allocation)] == 0);
  const auto st = service.stats("log_chatty");
  // Every call is accounted for: written, suppressed by the rate limit, or dropped (port full).
  CHECK(st.lines + st.suppressed + dropped == 1'000'000 + 1'000);
  CHECK(tail->total() > 0);
}
#endif
