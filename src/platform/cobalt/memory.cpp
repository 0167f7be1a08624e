// Cobalt process set-up: libcobalt has already locked memory; vigil confirms it, tunes malloc and
// prefaults like on Linux.
//
// libcobalt's initialisation (before main() with the default auto-init) calls
// mlockall(MCL_CURRENT | MCL_FUTURE) and aborts the program if that fails; a thread shadowed while
// memory is unlocked gets SIGDEBUG_NOMLOCK (XENOMAI.md §3.4). So memory is always locked here and
// must stay locked: `lock_memory = false` cannot unlock it (munlockall would break Cobalt).
#include "vigil/platform/memory.hpp"

#include "platform/cobalt/build_check.hpp"

#include <alloca.h>
#include <malloc.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>

namespace vigil::platform {

namespace {

bool fifo_allowed() noexcept {
  // libcobalt sets the Linux side of every SCHED_FIFO thread with glibc's pthread_setschedparam,
  // so the Linux rules apply: root/CAP_SYS_NICE, or an RLIMIT_RTPRIO above 0.
  if (geteuid() == 0) return true;
  rlimit rl{};
  return getrlimit(RLIMIT_RTPRIO, &rl) == 0 && rl.rlim_cur > 0;
}

}  // namespace

void prefault_stack(std::size_t bytes) noexcept {
  if (bytes == 0) return;
  // alloca reserves the frame below us; touching one byte per page maps every page of it. No
  // system call (the page size comes from the auxiliary vector), so a primary-mode thread stays
  // there; with memory locked by libcobalt the pages are normally present already.
  auto* base = static_cast<volatile unsigned char*>(alloca(bytes));
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  for (std::size_t i = 0; i < bytes; i += page) base[i] = 0;
  base[bytes - 1] = 0;
}

RealtimeSetupReport setup_realtime_process(const RealtimeSetupOptions& options) {
  RealtimeSetupReport report;
  // Repeating libcobalt's mlockall is harmless (same flags) and lets the report say what the
  // kernel answers now rather than assume it; it runs whatever `lock_memory` says.
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    report.memory_locked = true;
  } else {
    report.lock_errno = errno;
  }
  // Keep freed memory in the process and never serve allocations with mmap, so that memory
  // prefaulted here stays mapped (and locked). glibc's malloc serves Cobalt programs too.
  report.malloc_tuned = mallopt(M_TRIM_THRESHOLD, -1) == 1 && mallopt(M_MMAP_MAX, 0) == 1;
  // Bound the arenas before the process's threads start allocating: an arena, once made, stays.
  if (options.malloc_arena_max > 0 && mallopt(M_ARENA_MAX, options.malloc_arena_max) == 1) {
    report.malloc_arena_max = options.malloc_arena_max;
  }
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
  return report;
}

}  // namespace vigil::platform
