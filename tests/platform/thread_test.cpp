#include "vigil/platform/thread.hpp"

#include <sched.h>

#include <atomic>
#include <catch2/catch.hpp>

#include "support/proc_reader.hpp"

using namespace vigil::platform;

TEST_CASE("Thread::spawn runs the body and reports the kernel tid", "[platform][thread]") {
  std::atomic<int> seen_tid{0};
  auto t = Thread::spawn({.name = "vigil-test"}, [&] { seen_tid = current_tid(); });
  REQUIRE(t.has_value());
  const int tid = t->tid();
  t->join();
  CHECK(tid > 0);
  CHECK(seen_tid == tid);
  CHECK_FALSE(t->joinable());
}

TEST_CASE("A FIFO thread reads back its policy, priority and CPU from /proc",
          "[platform][thread]") {
  if (!vigil::test::have_rt_privileges()) {
    WARN("skipped: no privilege for SCHED_FIFO");
    return;
  }
  const int cpu = cpu_count() > 1 ? 1 : 0;
  std::atomic<bool> release{false};
  std::atomic<bool> ready{false};
  SchedInfo inside{};
  auto t = Thread::spawn(
      {.name = "vigil-fifo", .policy = SchedPolicy::Fifo, .priority = 80, .cpu = cpu}, [&] {
        inside = current_sched_info().value();
        ready = true;
        while (!release) sched_yield();
      });
  REQUIRE(t.has_value());
  while (!ready) sched_yield();
  const auto proc = vigil::test::read_proc_thread(t->tid());
  release = true;
  t->join();
  CHECK(proc.policy == SCHED_FIFO);
  CHECK(proc.rt_priority == 80);
  CHECK(proc.cpus_allowed == std::to_string(cpu));
  CHECK(inside.policy == SchedPolicy::Fifo);
  CHECK(inside.priority == 80);
  CHECK(inside.pinned_cpu == cpu);
}

TEST_CASE("An OTHER thread reads back as SCHED_OTHER with priority 0", "[platform][thread]") {
  std::atomic<bool> release{false};
  std::atomic<bool> ready{false};
  auto t = Thread::spawn({.name = "vigil-other"}, [&] {
    ready = true;
    while (!release) sched_yield();
  });
  REQUIRE(t.has_value());
  while (!ready) sched_yield();
  const auto proc = vigil::test::read_proc_thread(t->tid());
  release = true;
  t->join();
  CHECK(proc.policy == SCHED_OTHER);
  CHECK(proc.rt_priority == 0);
}

TEST_CASE("Thread::spawn refuses bad configurations with an error, never a downgrade",
          "[platform][thread]") {
  bool ran = false;
  SECTION("priority out of range") {
    auto t = Thread::spawn({.name = "bad", .policy = SchedPolicy::Fifo, .priority = 120},
                           [&] { ran = true; });
    REQUIRE_FALSE(t.has_value());
    CHECK(t.error().code == EINVAL);
    CHECK(t.error().message.find("priority 120") != std::string::npos);
  }
  SECTION("cpu that does not exist") {
    auto t = Thread::spawn({.name = "bad", .cpu = 4096}, [&] { ran = true; });
    REQUIRE_FALSE(t.has_value());
    CHECK(t.error().code == EINVAL);
    CHECK(t.error().message.find("cpu 4096") != std::string::npos);
  }
  CHECK_FALSE(ran);
}

TEST_CASE("Thread names are set (truncated to 15 characters)", "[platform][thread]") {
  std::atomic<bool> release{false};
  std::atomic<bool> ready{false};
  auto t = Thread::spawn({.name = "vigil-a-very-long-thread-name"}, [&] {
    ready = true;
    while (!release) sched_yield();
  });
  REQUIRE(t.has_value());
  while (!ready) sched_yield();
  std::ifstream comm("/proc/self/task/" + std::to_string(t->tid()) + "/comm");
  std::string name;
  std::getline(comm, name);
  release = true;
  t->join();
  CHECK(name == "vigil-a-very-lo");
}
