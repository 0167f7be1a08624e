// Process set-up for real time on both platforms: mlockall, malloc tuning, stack and heap
// prefaulting, the zero-CPU-latency request. The one difference, whether memory may stay
// unlocked, comes from the backend (backend.hpp): libcobalt locks it when it starts (initialize()).
#include "vigil/platform/memory.hpp"

#include <alloca.h>
#include <fcntl.h>
#include <malloc.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>

#include "platform/posix/backend.hpp"
#include "vigil/platform/process.hpp"

namespace vigil::platform {

namespace {

bool fifo_allowed() noexcept {
  // Privilege probe without changing anything: root/CAP_SYS_NICE, or an RLIMIT_RTPRIO above 0.
  // Cobalt too: libcobalt sets the Linux side of every SCHED_FIFO thread with glibc's
  // pthread_setschedparam, so the Linux rules apply.
  if (geteuid() == 0) return true;
  rlimit rl{};
  return getrlimit(RLIMIT_RTPRIO, &rl) == 0 && rl.rlim_cur > 0;
}

}  // namespace

void prefault_stack(std::size_t bytes) noexcept {
  if (bytes == 0) return;
  // alloca reserves the frame below us; touching one byte per page maps every page of it. No
  // system call (the page size comes from the auxiliary vector), so a Cobalt thread in primary
  // mode stays there; with memory locked the pages are normally present already.
  auto* base = static_cast<volatile unsigned char*>(alloca(bytes));
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  for (std::size_t i = 0; i < bytes; i += page) base[i] = 0;
  base[bytes - 1] = 0;
}

int bound_malloc_arenas(int max) noexcept {
  return max > 0 && mallopt(M_ARENA_MAX, max) == 1 ? max : 0;
}

RealtimeSetupReport setup_realtime_process(const RealtimeSetupOptions& options) {
  RealtimeSetupReport report;
  // Cobalt: libcobalt starts here unless the program started it (it locks memory itself).
  if (auto core = initialize(); !core) report.core_error = core.error().message;
  // Cobalt: repeating libcobalt's mlockall is harmless (same flags) and lets the report say what
  // the kernel answers now rather than assume it; it runs whatever `lock_memory` says, since
  // memory must never be unlocked under Cobalt (munlockall would break it).
  if (options.lock_memory || detail::memory_always_locked()) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      report.memory_locked = true;
    } else {
      report.lock_errno = errno;
    }
  }
  // Keep freed memory in the process and never serve allocations with mmap, so that memory
  // prefaulted here stays mapped (and locked). glibc's malloc serves Cobalt programs too.
  report.malloc_tuned = mallopt(M_TRIM_THRESHOLD, -1) == 1 && mallopt(M_MMAP_MAX, 0) == 1;
  // Bound the arenas before the process's threads start allocating: an arena, once made, stays.
  report.malloc_arena_max = bound_malloc_arenas(options.malloc_arena_max);
  if (options.prefault_heap_bytes > 0) {
    if (void* p = std::malloc(options.prefault_heap_bytes)) {
      const long page = sysconf(_SC_PAGESIZE);
      auto* bytes = static_cast<volatile unsigned char*>(p);
      for (std::size_t i = 0; i < options.prefault_heap_bytes;
           i += static_cast<std::size_t>(page)) {
        bytes[i] = 0;
      }
      std::free(p);
      report.heap_prefaulted = options.prefault_heap_bytes;
    }
  }
  prefault_stack(options.prefault_stack_bytes);
  report.stack_prefaulted = options.prefault_stack_bytes;
  report.can_use_fifo = fifo_allowed();
  if (options.request_zero_cpu_latency) {
    // The request lasts while the file stays open: the descriptor is kept for the process's
    // life on purpose (one per process; a second call reuses it).
    static int fd = -1;
    if (fd < 0) {
      fd = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
      const std::int32_t zero = 0;
      if (fd >= 0 && ::write(fd, &zero, sizeof zero) != static_cast<ssize_t>(sizeof zero)) {
        ::close(fd);
        fd = -1;
      }
    }
    report.cpu_latency_requested = fd >= 0;
  }
  return report;
}

HugePageBlocks::HugePageBlocks(std::size_t block_bytes) noexcept
    : block_((block_bytes + 63) / 64 * 64),
      per_region_(block_ == 0 || block_ > kRegionBytes ? 0 : kRegionBytes / block_) {}

HugePageBlocks::~HugePageBlocks() {
  for (void* r : regions_) ::munmap(r, kRegionBytes);
}

void* HugePageBlocks::allocate() {
  if (!free_.empty()) {
    void* b = free_.back();
    free_.pop_back();
    ++in_use_;
    return b;
  }
  if (per_region_ == 0) return nullptr;
  if (regions_.empty() || carved_ == per_region_) {
    // Twice the size, trimmed to a region on a 2 MiB boundary (huge pages need the alignment).
    // Mapped without access first: under mlockall(MCL_FUTURE) a readable mapping is made resident
    // at once, before the advice could apply; mprotect() then makes it resident with the advice.
    regions_.reserve(regions_.size() + 1);  // so that push_back below cannot throw after mmap
    void* raw = ::mmap(nullptr, 2 * kRegionBytes, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw == MAP_FAILED) return nullptr;
    // Pointer arithmetic from the mapping (no integer-to-pointer cast): the head to drop, then
    // the region, then the tail to drop (kRegionBytes - head).
    const auto at = reinterpret_cast<std::uintptr_t>(raw);
    const std::size_t head = ((at + kRegionBytes - 1) & ~std::uintptr_t{kRegionBytes - 1}) - at;
    char* const region = static_cast<char*>(raw) + head;
    if (head > 0) ::munmap(raw, head);
    if (head < kRegionBytes) ::munmap(region + kRegionBytes, kRegionBytes - head);
#if defined(MADV_HUGEPAGE)
    if (::madvise(region, kRegionBytes, MADV_HUGEPAGE) != 0 && advice_errno_ == 0) {
      advice_errno_ = errno;
    }
#else
    if (advice_errno_ == 0) advice_errno_ = ENOSYS;
#endif
    if (::mprotect(region, kRegionBytes, PROT_READ | PROT_WRITE) != 0) {
      ::munmap(region, kRegionBytes);
      return nullptr;
    }
    regions_.push_back(region);
    carved_ = 0;
  }
  ++in_use_;
  // Room for every block in use on the free list: release() never allocates (it is called from
  // destructors).
  if (free_.capacity() < in_use_) free_.reserve(2 * in_use_);
  return static_cast<char*>(regions_.back()) + block_ * carved_++;
}

void HugePageBlocks::release(void* block) noexcept {
  if (block == nullptr) return;
  free_.push_back(block);
  --in_use_;
}

}  // namespace vigil::platform
