#include "vigil/platform/memory.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "support/proc_reader.hpp"
#include "vigil/build_config.hpp"
#include "vigil/platform/thread.hpp"

using namespace vigil::platform;

constexpr bool kCobalt = VIGIL_PLATFORM_COBALT != 0;

TEST_CASE("setup_realtime_process reports every step and locks memory when privileged",
          "[platform][memory]") {
  const auto report = setup_realtime_process({.lock_memory = true,
                                              .prefault_stack_bytes = 128 * 1024,
                                              .prefault_heap_bytes = 1024 * 1024});
  CHECK(report.stack_prefaulted == 128 * 1024);
  CHECK(report.heap_prefaulted == 1024 * 1024);
  CHECK(report.describe().find("memory locked: ") != std::string::npos);
  // /proc/self/status "VmLck" is non-zero exactly when pages are locked.
  std::ifstream status("/proc/self/status");
  std::string line;
  long vmlck = -1;
  while (std::getline(status, line)) {
    if (line.rfind("VmLck:", 0) == 0) vmlck = std::stol(line.substr(6));
  }
  if (report.memory_locked) {
#if !defined(VIGIL_SANITIZER_BUILD)  // sanitizers intercept mlockall and do nothing
    CHECK(vmlck > 0);
#else
    (void)vmlck;
#endif
    // Leave the rest of the suite as it was. Never on Cobalt: libcobalt locked memory before
    // main(), and a thread shadowed while it is unlocked is killed (SIGDEBUG_NOMLOCK).
    if constexpr (!kCobalt) munlockall();
  } else {
    CHECK(report.lock_errno != 0);
  }
  CHECK(report.can_use_fifo == vigil::test::have_rt_privileges());
  // The PM QoS request is kept for the process's life where the kernel offers it to us.
  if (vigil::test::have_rt_privileges() && std::ifstream("/dev/cpu_dma_latency").good()) {
    CHECK(report.cpu_latency_requested);
  }
  CHECK(report.describe().find("zero CPU latency requested: ") != std::string::npos);
}

TEST_CASE("On Cobalt memory stays locked even when the caller does not ask for it",
          "[platform][memory]") {
  const auto report = setup_realtime_process(
      {.lock_memory = false, .prefault_stack_bytes = 0, .prefault_heap_bytes = 0});
  if constexpr (kCobalt) {
    CHECK(report.memory_locked);  // libcobalt locked it; vigil confirms and never unlocks
  } else {
    CHECK_FALSE(report.memory_locked);  // not asked for: mlockall is not called
    CHECK(report.lock_errno == 0);
  }
}

TEST_CASE("prefault_stack takes the stack's page faults up front", "[platform][memory]") {
  // Run in a fresh thread whose stack is untouched: faulting 512 KiB of it in costs >= 100 minor
  // faults the first time and (nearly) none the second. 12 MiB: larger than any stack an earlier
  // test's thread had, so glibc cannot hand this thread a cached stack (it reuses one of up to 4x
  // the size asked) whose pages an earlier mlockall made resident.
  std::uint64_t first = 0;
  std::uint64_t second = 0;
  auto t = Thread::spawn(
      {.name = "prefault", .stack_bytes = 12 * 1024 * 1024, .prefault_stack_bytes = 0}, [&] {
        const int tid = current_tid();
        auto a = vigil::test::read_proc_thread(tid).minflt;
        prefault_stack(512 * 1024);
        auto b = vigil::test::read_proc_thread(tid).minflt;
        prefault_stack(512 * 1024);
        auto c = vigil::test::read_proc_thread(tid).minflt;
        first = b - a;
        second = c - b;
      });
  REQUIRE(t.has_value());
  t->join();
  CHECK(first >= 100);
  CHECK(second < first / 4);
}

namespace {
// The VmFlags line of the /proc/self/smaps entry that maps `p` ("" when none does).
std::string vm_flags_of(const void* p) {
  const auto at = reinterpret_cast<std::uintptr_t>(p);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t lo = 0;
    std::uintptr_t hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= at && at < hi;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      return line;
    }
  }
  return {};
}
}  // namespace

TEST_CASE("Huge-page blocks are carved from aligned regions, advised, and reused once released",
          "[platform][memory]") {
  constexpr std::size_t kRegion = HugePageBlocks::kRegionBytes;
  HugePageBlocks blocks(32 * 1024 + 5);  // rounded up to a cache line
  CHECK(blocks.block_bytes() == 32 * 1024 + 64);
  const std::size_t per = blocks.blocks_per_region();
  CHECK(per == kRegion / (32 * 1024 + 64));
  CHECK(blocks.mapped_bytes() == 0);  // nothing mapped before a block is asked for

  std::vector<unsigned char*> got;
  for (std::size_t i = 0; i < per + 3; ++i) {
    auto* b = static_cast<unsigned char*>(blocks.allocate());
    REQUIRE(b != nullptr);
    CHECK(reinterpret_cast<std::uintptr_t>(b) % 64 == 0);
    std::memset(b, static_cast<int>(i & 0xFFU), blocks.block_bytes());  // writable, all of it
    got.push_back(b);
  }
  CHECK(blocks.mapped_bytes() == 2 * kRegion);  // the 4 last blocks opened a second region
  CHECK(blocks.in_use() == per + 3);
  // Each region starts on a 2 MiB boundary (a huge page needs it), and no two blocks overlap.
  CHECK(reinterpret_cast<std::uintptr_t>(got[0]) % kRegion == 0);
  CHECK(reinterpret_cast<std::uintptr_t>(got[per]) % kRegion == 0);
  auto sorted = got;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    CHECK(sorted[i] - sorted[i - 1] >= static_cast<std::ptrdiff_t>(blocks.block_bytes()));
  }
  for (std::size_t i = 0; i < got.size(); ++i) {
    CHECK(got[i][0] == (i & 0xFFU));  // what was written stayed
    CHECK(got[i][blocks.block_bytes() - 1] == (i & 0xFFU));
  }
  // The kernel took the advice: the region's mapping carries the huge-page flag ("hg").
  if (blocks.advice_errno() == 0) {
    CHECK_THAT(vm_flags_of(got[0]), Catch::Contains(" hg"));
    CHECK_THAT(vm_flags_of(got[per]), Catch::Contains(" hg"));
  } else {
    WARN("madvise(MADV_HUGEPAGE) refused here (errno " << blocks.advice_errno() << ")");
  }
  // A released block is handed out again before any new memory.
  blocks.release(got[5]);
  CHECK(blocks.in_use() == per + 2);
  CHECK(blocks.allocate() == got[5]);
  CHECK(blocks.mapped_bytes() == 2 * kRegion);
  for (auto* b : got) blocks.release(b);
  CHECK(blocks.in_use() == 0);

  // Blocks larger than a region: none (the caller allocates elsewhere).
  HugePageBlocks too_large(kRegion + 1);
  CHECK(too_large.blocks_per_region() == 0);
  CHECK(too_large.allocate() == nullptr);
  CHECK(too_large.mapped_bytes() == 0);
}
