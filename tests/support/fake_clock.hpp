#pragma once
// A clock the test sets by hand, for ManualActivity, supervision and the monitor.
#include <atomic>

#include "vigil/platform/clock.hpp"

namespace vigil::test {

struct FakeClock {
  std::atomic<Nanos> now_ns{1'000'000'000};

  [[nodiscard]] Clock clock() const noexcept { return Clock{&read, this}; }
  void set(Nanos t) noexcept { now_ns.store(t, std::memory_order_relaxed); }
  void advance(Nanos d) noexcept { now_ns.fetch_add(d, std::memory_order_relaxed); }
  [[nodiscard]] Nanos now() const noexcept { return now_ns.load(std::memory_order_relaxed); }

  static Nanos read(const void* self) noexcept {
    return static_cast<const FakeClock*>(self)->now_ns.load(std::memory_order_relaxed);
  }
};

}  // namespace vigil::test
