#include "vigil/platform/wait.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <thread>

using namespace vigil::platform;

TEST_CASE("wait_on returns at once when the word differs", "[platform][wait]") {
  std::atomic<std::uint32_t> w{1};
  wait_on(w, 0);
  SUCCEED();
}

TEST_CASE("wait_on honours its deadline", "[platform][wait]") {
  std::atomic<std::uint32_t> w{0};
  const auto deadline = now_ns() + 20 * vigil::kNanosPerMilli;
  while (now_ns() < deadline) wait_on(w, 0, deadline);
  CHECK(now_ns() >= deadline);
}

TEST_CASE("wake_one wakes a waiter", "[platform][wait]") {
  std::atomic<std::uint32_t> w{0};
  std::atomic<bool> woke{false};
  std::thread waiter([&] {
    while (w.load() == 0) wait_on(w, 0);
    woke = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(10));
  w.store(1);
  wake_one(w);
  waiter.join();
  CHECK(woke);
}
