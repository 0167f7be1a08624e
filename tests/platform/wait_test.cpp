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

// --- ReadySet (epoll): what the daemon waits on -----------------------------------------------

#include <sys/wait.h>
#include <unistd.h>

#include "vigil/platform/process_watch.hpp"
#include "vigil/platform/ready_set.hpp"

TEST_CASE("ReadySet waits until its deadline when nothing is ready", "[platform][wait]") {
  auto set = ReadySet::open();
  REQUIRE(set.has_value());
  int p[2];
  REQUIRE(::pipe(p) == 0);
  REQUIRE(set->add(p[0], 7).has_value());
  std::uint64_t tags[4] = {};
  const auto deadline = now_ns() + 20 * vigil::kNanosPerMilli;
  CHECK(set->wait(deadline, tags, 4) == 0);
  CHECK(now_ns() >= deadline);
  CHECK(set->wait(0, tags, 4) == 0);  // no wait at all
  ::close(p[0]);
  ::close(p[1]);
}

TEST_CASE("ReadySet reports the ready descriptors by tag, and no removed one", "[platform][wait]") {
  auto set = ReadySet::open();
  REQUIRE(set.has_value());
  int a[2];
  int b[2];
  REQUIRE(::pipe(a) == 0);
  REQUIRE(::pipe(b) == 0);
  REQUIRE(set->add(a[0], 1).has_value());
  REQUIRE(set->add(b[0], 2).has_value());
  CHECK_FALSE(set->add(a[0], 3).has_value());  // already watched: the error is returned
  REQUIRE(::write(b[1], "x", 1) == 1);
  std::uint64_t tags[4] = {};
  REQUIRE(set->wait(now_ns() + vigil::kNanosPerSecond, tags, 4) == 1);
  CHECK(tags[0] == 2);
  // Level-triggered: still ready until read.
  CHECK(set->wait(0, tags, 4) == 1);
  set->remove(b[0]);
  CHECK(set->wait(0, tags, 4) == 0);
  for (int fd : {a[0], a[1], b[0], b[1]}) ::close(fd);
}

TEST_CASE("ReadySet wakes a waiter when a watched process ends", "[platform][wait]") {
  const pid_t child = ::fork();
  if (child == 0) {
    ::usleep(30'000);
    ::_exit(0);
  }
  REQUIRE(child > 0);
  const auto ticks = process_start_ticks(child);
  REQUIRE(ticks.has_value());
  auto watch = ProcessWatch::open({child, *ticks});
  REQUIRE(watch.has_value());
  if (watch->fd() < 0) {
    ::waitpid(child, nullptr, 0);
    SUCCEED("no pidfd on this kernel: the daemon polls /proc instead");
    return;
  }
  auto set = ReadySet::open();
  REQUIRE(set.has_value());
  REQUIRE(set->add(watch->fd(), 42).has_value());
  std::uint64_t tags[2] = {};
  const int n = set->wait(now_ns() + 5 * vigil::kNanosPerSecond, tags, 2);
  CHECK(n == 1);
  CHECK(tags[0] == 42);
  ::waitpid(child, nullptr, 0);
}
