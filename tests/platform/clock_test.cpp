#include "vigil/platform/clock.hpp"

#include <signal.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <thread>

using vigil::Nanos;
using vigil::platform::now_ns;
using vigil::platform::sleep_until;

TEST_CASE("now_ns is monotonic and counts nanoseconds", "[platform][clock]") {
  Nanos prev = now_ns();
  for (int i = 0; i < 100000; ++i) {
    const Nanos t = now_ns();
    REQUIRE(t >= prev);
    prev = t;
  }
  const Nanos a = now_ns();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const Nanos b = now_ns();
  CHECK(b - a >= 20 * vigil::kNanosPerMilli);
}

TEST_CASE("sleep_until never returns before the deadline", "[platform][clock]") {
  for (int i = 0; i < 20; ++i) {
    const Nanos deadline = now_ns() + 500 * vigil::kNanosPerMicro;
    REQUIRE(sleep_until(deadline) == 0);
    REQUIRE(now_ns() >= deadline);
  }
}

TEST_CASE("sleep_until returns at once for a past deadline and rejects a negative one",
          "[platform][clock]") {
  CHECK(sleep_until(now_ns() - vigil::kNanosPerSecond) == 0);
  CHECK(sleep_until(-1) == EINVAL);
}

namespace {
void on_usr1(int) {}
}  // namespace

TEST_CASE("sleep_until resumes after a signal interrupts it (EINTR)", "[platform][clock]") {
  struct sigaction sa {};
  sa.sa_handler = &on_usr1;  // no SA_RESTART: clock_nanosleep returns EINTR
  struct sigaction old {};
  sigaction(SIGUSR1, &sa, &old);
  std::atomic<bool> asleep{false};
  Nanos deadline = 0;
  Nanos woke = 0;
  int rc = -1;
  std::thread sleeper([&] {
    deadline = now_ns() + 200 * vigil::kNanosPerMilli;
    asleep = true;
    rc = sleep_until(deadline);
    woke = now_ns();
  });
  while (!asleep) std::this_thread::yield();
  for (int i = 0; i < 5; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    pthread_kill(sleeper.native_handle(), SIGUSR1);
  }
  sleeper.join();
  sigaction(SIGUSR1, &old, nullptr);
  CHECK(rc == 0);
  CHECK(woke >= deadline);
}

namespace {
Nanos fake_now(const void* ctx) noexcept { return *static_cast<const Nanos*>(ctx); }
}  // namespace

TEST_CASE("Clock defaults to the monotonic clock and can be replaced", "[platform][clock]") {
  const vigil::Clock sys = vigil::Clock::system();
  const Nanos a = now_ns();
  CHECK(sys.now() >= a);
  Nanos t = 42;
  const vigil::Clock fake{&fake_now, &t};
  CHECK(fake.now() == 42);
  t = 1000;
  CHECK(fake.now() == 1000);
}
