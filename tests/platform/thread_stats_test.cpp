#include "vigil/platform/thread_stats.hpp"

#include <sched.h>
#include <time.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <thread>

#include "support/proc_reader.hpp"

using namespace vigil::platform;

namespace {
// A thread that does what the test asks between two barriers, so that readings are stable.
struct Worker {
  std::atomic<int> step{0};
  std::atomic<int> done{0};
  std::function<void(int)> action;
  vigil::expected<Thread, vigil::Error> thread;

  explicit Worker(std::function<void(int)> a) : action(std::move(a)) {
    thread = Thread::spawn({.name = "stats-worker"}, [this] {
      for (int s = 1; s <= 3; ++s) {
        while (step.load() < s) sched_yield();
        action(s);
        done = s;
      }
    });
  }
  void run(int s) {
    step = s;
    while (done.load() < s) std::this_thread::yield();
  }
};
}  // namespace

TEST_CASE("read_thread_stats agrees with /proc and sees context switches when a thread sleeps",
          "[platform][thread_stats]") {
  Worker w([](int s) {
    if (s == 2) {
      for (int i = 0; i < 20; ++i) std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  });
  REQUIRE(w.thread.has_value());
  const int tid = w.thread->tid();
  w.run(1);
  const auto a = read_thread_stats(tid);
  const auto pa = vigil::test::read_proc_thread(tid);
  w.run(2);
  const auto b = read_thread_stats(tid);
  const auto pb = vigil::test::read_proc_thread(tid);
  REQUIRE(a.has_value());
  REQUIRE(b.has_value());
  CHECK(a->tid == tid);
  CHECK(a->name == "stats-worker");
  CHECK(a->voluntary_switches == pa.voluntary);
  CHECK(a->minor_faults == pa.minflt);
  CHECK(b->voluntary_switches == pb.voluntary);
  CHECK(b->involuntary_switches == pb.involuntary);
  CHECK(b->minor_faults == pb.minflt);
  CHECK(b->major_faults == pb.majflt);
  CHECK(b->voluntary_switches - a->voluntary_switches >= 20);
  CHECK(b->policy == SchedPolicy::Other);
  CHECK(b->last_cpu >= 0);
  w.run(3);
  w.thread->join();
}

TEST_CASE("read_thread_stats fails with ENOENT or ESRCH for a thread that does not exist",
          "[platform][thread_stats]") {
  const auto r = read_thread_stats(0x7ffffff0);
  REQUIRE_FALSE(r.has_value());
  CHECK((r.error().code == ENOENT || r.error().code == ESRCH));
  CHECK(r.error().message.find("/proc/self/task/") != std::string::npos);
}

TEST_CASE("read_thread_stats counts CPU time", "[platform][thread_stats]") {
  Worker w([](int s) {
    if (s == 2) {
      // Burn 60 ms of this thread's CPU time (not wall time: the machine may be busy).
      auto cpu_now = [] {
        timespec ts{};
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
        return ts.tv_sec * vigil::kNanosPerSecond + ts.tv_nsec;
      };
      const auto end = cpu_now() + 60 * vigil::kNanosPerMilli;
      volatile std::uint64_t x = 0;
      while (cpu_now() < end) x = x + 1;
    }
  });
  REQUIRE(w.thread.has_value());
  w.run(1);
  const auto a = read_thread_stats(w.thread->tid()).value();
  w.run(2);
  const auto b = read_thread_stats(w.thread->tid()).value();
  w.run(3);
  w.thread->join();
  const auto cpu = (b.user_time_ns + b.system_time_ns) - (a.user_time_ns + a.system_time_ns);
  CHECK(cpu >= 40 * vigil::kNanosPerMilli);  // 60 ms burnt, tick resolution 10 ms
}
