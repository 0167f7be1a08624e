#include "vigil/platform/rt_loss.hpp"

#include <sys/mman.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <cstring>
#include <thread>

#include "support/proc_reader.hpp"
#include "vigil/build_config.hpp"
#include "vigil/platform/thread.hpp"

using namespace vigil::platform;

// Cobalt: thread_usage() reads nothing (getrusage would relax a primary-mode thread on every
// cycle; the mode-switch detector replaces the blocking and page-fault ones), so the Linux cases
// below check that it stays at zero instead.
constexpr bool kCobalt = VIGIL_PLATFORM_COBALT != 0;

TEST_CASE("thread_usage counts the calling thread's voluntary switches", "[platform][rt_loss]") {
  if constexpr (kCobalt) {
    for (int i = 0; i < 10; ++i) std::this_thread::sleep_for(std::chrono::microseconds(100));
    const auto u = thread_usage();
    CHECK(u.voluntary_switches == 0);
    CHECK(u.minor_faults == 0);
    return;
  }
  const auto a = thread_usage();
  for (int i = 0; i < 10; ++i) std::this_thread::sleep_for(std::chrono::microseconds(100));
  const auto b = thread_usage();
  CHECK(b.voluntary_switches - a.voluntary_switches >= 10);
}

TEST_CASE("thread_usage counts minor faults on fresh pages", "[platform][rt_loss]") {
  constexpr std::size_t kPages = 64;
  const std::size_t page = 4096;
  void* mem =
      mmap(nullptr, kPages * page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  REQUIRE(mem != MAP_FAILED);
  if constexpr (kCobalt) {
    auto* bytes = static_cast<volatile unsigned char*>(mem);
    for (std::size_t i = 0; i < kPages; ++i) bytes[i * page] = 1;
    CHECK(thread_usage().minor_faults == 0);
    munmap(mem, kPages * page);
    return;
  }
  const auto a = thread_usage();
  auto* bytes = static_cast<volatile unsigned char*>(mem);
  for (std::size_t i = 0; i < kPages; ++i) bytes[i * page] = 1;
  const auto b = thread_usage();
  munmap(mem, kPages * page);
  CHECK(b.minor_faults - a.minor_faults >= kPages);
  CHECK(b.major_faults == a.major_faults);
}

TEST_CASE("thread_usage agrees with /proc for the calling thread", "[platform][rt_loss]") {
  if constexpr (kCobalt) {
    SUCCEED("Cobalt: thread_usage() reads no kernel counter (checked above)");
    return;
  }
  const int tid = current_tid();
  const auto u = thread_usage();
  const auto p = vigil::test::read_proc_thread(tid);
  const auto u2 = thread_usage();
  // Reading /proc may itself fault or switch; the kernel figure lies between the two readings.
  CHECK(p.voluntary >= u.voluntary_switches);
  CHECK(p.voluntary <= u2.voluntary_switches);
  CHECK(p.minflt >= u.minor_faults);
  CHECK(p.minflt <= u2.minor_faults);
}

TEST_CASE("Without alloc_guard, allocation counting is unavailable and reads 0",
          "[platform][rt_loss]") {
  CHECK_FALSE(allocation_counting_available());
  auto* p = new int(3);
  CHECK(thread_allocations() == 0);
  delete p;
}

TEST_CASE("Mode-switch detection: a no-op on Linux, refused to threads Cobalt does not manage",
          "[platform][rt_loss]") {
  CHECK(std::strcmp(to_string(LossCause::Blocking), "blocking") == 0);
  if constexpr (kCobalt) {
    // A thread that Cobalt does not manage (std::thread: libstdc++ calls glibc's pthread_create)
    // cannot be armed, and counts nothing.
    bool armed = true;
    std::thread([&] { armed = arm_mode_switch_detection(); }).join();
    CHECK_FALSE(armed);
    return;
  }
  CHECK_FALSE(arm_mode_switch_detection());
  CHECK(thread_mode_switches() == 0);
}

TEST_CASE("Cobalt: a FIFO thread is a Cobalt thread whose Linux system calls count as switches",
          "[platform][rt_loss]") {
  if constexpr (!kCobalt) {
    SUCCEED("Linux: no mode switches (checked above)");
    return;
  }
  if (!vigil::test::have_rt_privileges()) {
    WARN("skipped: no privilege for SCHED_FIFO");
    return;
  }
  bool armed = false;
  std::uint64_t before = 0;
  std::uint64_t after = 0;
  const auto reasons_before = mode_switch_reasons();
  auto t =
      Thread::spawn({.name = "vigil-cobalt", .policy = SchedPolicy::Fifo, .priority = 10}, [&] {
        armed = arm_mode_switch_detection();
        before = thread_mode_switches();
        // A plain Linux system call: relaxes the thread, SIGDEBUG says why.
        ::syscall(SYS_getppid);
        after = thread_mode_switches();
      });
  REQUIRE(t.has_value());
  t->join();
  CHECK(armed);
  CHECK(after >= before + 1);
  CHECK(mode_switch_reasons().syscall >= reasons_before.syscall + 1);
}
