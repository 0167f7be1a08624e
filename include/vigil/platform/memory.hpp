#pragma once
/// @file
/// Process set-up for real time: memory locking and prefaulting. Call once, early in main(),
/// before real-time threads start. None of these functions is RT-safe.

#include <cstddef>
#include <string>
#include <vector>

namespace vigil::platform {

/// What `setup_realtime_process` should do.
struct RealtimeSetupOptions {
  /// mlockall(MCL_CURRENT | MCL_FUTURE): no page of the process is ever paged out.
  bool lock_memory = true;
  /// Bytes of the calling thread's stack to touch now.
  std::size_t prefault_stack_bytes = std::size_t{256} * 1024;
  /// Bytes of heap to allocate, touch and give back to malloc, which then keeps them
  /// (M_TRIM_THRESHOLD and M_MMAP_MAX are set so that glibc neither returns nor mmaps them).
  /// 4 MiB: more than a deployment of a few dozen components allocates after start (the demo
  /// allocates about 1 MB), so later allocations are served from memory already resident.
  /// Under mlockall the heap's later growth is locked and made resident by the kernel at the
  /// moment it grows, so a smaller value costs a brk() call, never a page fault in a cycle.
  /// Every prefaulted byte stays resident (and locked) for the life of the process.
  std::size_t prefault_heap_bytes = std::size_t{4} * 1024 * 1024;
  /// Upper bound on glibc's malloc arenas (mallopt M_ARENA_MAX); 0 keeps glibc's default
  /// (8 per CPU on 64-bit). 1, the default: every thread allocates from the main heap, the one
  /// prefaulted above. With more arenas, a thread that allocates gets an arena of its own, which
  /// reserves 64 MiB of address space (counted in VmLck under mlockall) and whose pages were never
  /// prefaulted. The cost of 1: threads that allocate at the same time share malloc's lock (a
  /// real-time thread must not allocate anyway; the allocation detector reports one that does).
  int malloc_arena_max = 1;
  /// Ask the kernel for zero CPU wake-up latency (PM QoS, /dev/cpu_dma_latency, as cyclictest
  /// does) for the life of the process: deep idle states are then not used, which on many
  /// machines changes wake-up latency more than anything else. Needs root.
  bool request_zero_cpu_latency = true;
};

/// What `setup_realtime_process` achieved. Every step reports success or the errno it failed with;
/// nothing is hidden, so the caller can print or act on it (e.g. warn that memory is not locked).
struct RealtimeSetupReport {
  bool memory_locked = false;
  int lock_errno = 0;  ///< errno of mlockall when it failed (EPERM, ENOMEM), else 0.
  bool malloc_tuned = false;
  /// The malloc arena bound in force (M_ARENA_MAX), or 0 when not set (glibc's default).
  int malloc_arena_max = 0;
  std::size_t stack_prefaulted = 0;
  std::size_t heap_prefaulted = 0;
  /// True when SCHED_FIFO threads can be created (privilege probe, nothing changed).
  bool can_use_fifo = false;
  /// The zero CPU latency request is in force (false when not asked for or refused).
  bool cpu_latency_requested = false;
  /// Empty, or why the platform's real-time core could not be started (platform::initialize(),
  /// process.hpp: Cobalt only, e.g. called from a thread other than main before Cobalt started).
  std::string core_error;

  /// One line per step, e.g. "memory locked: yes", for logs and reports.
  [[nodiscard]] std::string describe() const;
};

/// Starts the platform's real-time core first (platform::initialize(): Cobalt's libcobalt; nothing
/// on Linux), then locks and prefaults memory as `options` says. Never throws; failures are in
/// the report.
RealtimeSetupReport setup_realtime_process(const RealtimeSetupOptions& options = {});

/// Bounds glibc's malloc arenas to `max` (mallopt M_ARENA_MAX), the step of
/// `setup_realtime_process` that must come before any other thread allocates: glibc makes a new
/// arena for each thread that allocates while fewer than 8 exist, whatever the bound set later,
/// and an arena, once made, stays (with its 64 MiB reserve, locked under mlockall). Call it
/// before starting threads that `setup_realtime_process` would otherwise follow (a server's).
/// Returns the bound now in force, or 0 when `max` <= 0 (nothing changed) or glibc refused it.
int bound_malloc_arenas(int max) noexcept;

/// Touches `bytes` of the calling thread's stack so later use takes no page fault.
void prefault_stack(std::size_t bytes) noexcept;

/// Blocks of one size carved from 2 MiB regions that the kernel is asked to back with huge
/// pages (madvise MADV_HUGEPAGE: Linux transparent huge pages, in their "always" or "madvise"
/// mode). For memory that a non-RT thread sweeps through, a little of each block at a time, across
/// thousands of blocks (the supervisor's flight rings): with 4 KiB pages every block visited is a
/// TLB miss, with 2 MiB pages one entry covers 64 rings of 32 KiB.
///
/// Regions are mapped as blocks are asked for, and unmapped when the pool is destroyed (every block
/// must have been released by then); released blocks are reused, never unmapped. Under
/// mlockall(MCL_FUTURE) a region is locked and made resident when it is mapped (after the advice,
/// so with huge pages where the kernel has them). Not RT-safe: allocate() maps memory.
class HugePageBlocks {
 public:
  static constexpr std::size_t kRegionBytes = std::size_t{2} * 1024 * 1024;

  /// Blocks of `block_bytes`, rounded up to a cache line; at most kRegionBytes (larger: none).
  explicit HugePageBlocks(std::size_t block_bytes) noexcept;
  ~HugePageBlocks();
  HugePageBlocks(const HugePageBlocks&) = delete;
  HugePageBlocks& operator=(const HugePageBlocks&) = delete;

  /// A block (64-byte aligned, contents unspecified), or null when none can be had (a region
  /// could not be mapped, or blocks are larger than a region): the caller allocates elsewhere.
  [[nodiscard]] void* allocate();
  /// Gives back a block from allocate(), for reuse. Never allocates.
  void release(void* block) noexcept;

  [[nodiscard]] std::size_t block_bytes() const noexcept { return block_; }
  [[nodiscard]] std::size_t blocks_per_region() const noexcept { return per_region_; }
  /// Bytes mapped (regions x kRegionBytes).
  [[nodiscard]] std::size_t mapped_bytes() const noexcept { return regions_.size() * kRegionBytes; }
  /// Blocks handed out and not released.
  [[nodiscard]] std::size_t in_use() const noexcept { return in_use_; }
  /// 0, or the errno of the first madvise(MADV_HUGEPAGE) refused (the regions then have ordinary
  /// pages: everything works, without the fewer TLB misses).
  [[nodiscard]] int advice_errno() const noexcept { return advice_errno_; }

 private:
  std::size_t block_ = 0;
  std::size_t per_region_ = 0;
  std::vector<void*> regions_;
  std::vector<void*> free_;
  std::size_t carved_ = 0;  // blocks handed out of the newest region
  std::size_t in_use_ = 0;
  int advice_errno_ = 0;
};

}  // namespace vigil::platform
