#include "vigil/platform/rt_loss.hpp"

#include <sys/mman.h>

#include <catch2/catch.hpp>
#include <cstring>
#include <thread>

#include "support/proc_reader.hpp"
#include "vigil/platform/thread.hpp"

using namespace vigil::platform;

TEST_CASE("thread_usage counts the calling thread's voluntary switches", "[platform][rt_loss]") {
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
  const auto a = thread_usage();
  auto* bytes = static_cast<volatile unsigned char*>(mem);
  for (std::size_t i = 0; i < kPages; ++i) bytes[i * page] = 1;
  const auto b = thread_usage();
  munmap(mem, kPages * page);
  CHECK(b.minor_faults - a.minor_faults >= kPages);
  CHECK(b.major_faults == a.major_faults);
}

TEST_CASE("thread_usage agrees with /proc for the calling thread", "[platform][rt_loss]") {
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

TEST_CASE("Mode-switch detection is a no-op on Linux", "[platform][rt_loss]") {
  CHECK_FALSE(arm_mode_switch_detection());
  CHECK(thread_mode_switches() == 0);
  CHECK(std::strcmp(to_string(LossCause::Blocking), "blocking") == 0);
}
