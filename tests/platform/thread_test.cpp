#include "vigil/platform/thread.hpp"

#include <sched.h>

#include <atomic>
#include <catch2/catch.hpp>

#include "support/proc_reader.hpp"
#include "vigil/build_config.hpp"
#include "vigil/platform/rt_loss.hpp"

using namespace vigil::platform;

constexpr bool kCobalt = VIGIL_PLATFORM_COBALT != 0;

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

TEST_CASE("The platform decides per thread: FIFO threads are Cobalt threads, others are not",
          "[platform][thread]") {
  // Only a Cobalt thread can be armed for mode-switch detection (Linux: never).
  bool other_armed = true;
  auto other =
      Thread::spawn({.name = "vigil-other"}, [&] { other_armed = arm_mode_switch_detection(); });
  REQUIRE(other.has_value());
  other->join();
  CHECK_FALSE(other_armed);
  if (!vigil::test::have_rt_privileges()) {
    WARN("skipped the FIFO half: no privilege for SCHED_FIFO");
    return;
  }
  bool fifo_armed = !kCobalt;
  auto fifo = Thread::spawn({.name = "vigil-fifo", .policy = SchedPolicy::Fifo, .priority = 10},
                            [&] { fifo_armed = arm_mode_switch_detection(); });
  REQUIRE(fifo.has_value());
  fifo->join();
  CHECK(fifo_armed == kCobalt);
}

TEST_CASE("Errors name the kind of thread that was refused", "[platform][thread]") {
  auto t = Thread::spawn({.name = "bad", .policy = SchedPolicy::Fifo, .priority = 120}, [] {});
  REQUIRE_FALSE(t.has_value());
  // Cobalt: SCHED_FIFO threads are Cobalt threads and say so; nothing is added on Linux.
  CHECK((t.error().message.find(", Cobalt)") != std::string::npos) == kCobalt);
}
