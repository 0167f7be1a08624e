#pragma once
// Private to the platform module (never installed): what the shared POSIX part of the platform
// layer (src/platform/posix/) asks of the implementation it is linked with. Each implementation
// folder defines these in its backend.cpp: src/platform/linux/ with glibc, src/platform/cobalt/
// with libcobalt (docs/design/platform.md, "One kind of thread, one kind of lock").
//
// This header includes no Xenomai header: the shared files are compiled with the plain compiler
// flags on both platforms.

#include <pthread.h>
#include <sched.h>

#include "vigil/platform/thread.hpp"

namespace vigil::platform::detail {

/// The pthread calls that make, name and join one kind of thread. Each returns 0 or a positive
/// error number, like POSIX.
struct ThreadOps {
  /// Appended to the thread's description in error messages ("" or ", Cobalt").
  const char* label;
  int (*attr_init)(pthread_attr_t* attr);
  int (*create)(pthread_t* thread, const pthread_attr_t* attr, void* (*start)(void*), void* arg);
  int (*join)(pthread_t thread, void** result);
  /// Called by the new thread on itself, before anything else.
  int (*set_name)(pthread_t thread, const char* name);
};

/// glibc's calls: a plain Linux thread. Defined in src/platform/posix/thread.cpp.
[[nodiscard]] const ThreadOps& glibc_thread_ops() noexcept;

/// Which kind of thread `config` gets on this platform: the one decision per thread of the
/// platform layer. Linux: always glibc's. Cobalt: libcobalt's for SCHED_FIFO (a Cobalt thread),
/// glibc's otherwise (a plain Linux thread, unknown to the Cobalt core).
[[nodiscard]] const ThreadOps& thread_ops(const ThreadConfig& config) noexcept;

/// Kernel thread id of the calling thread, asked of the kernel (current_tid() caches it).
[[nodiscard]] int query_current_tid() noexcept;

/// pthread_getschedparam of the calling thread as the platform's scheduler sees it.
[[nodiscard]] int current_sched_param(int* policy, sched_param* param) noexcept;

/// True when memory is locked whatever RealtimeSetupOptions::lock_memory says (Cobalt: once
/// libcobalt has started, initialize(): it locked memory, which must never be unlocked).
[[nodiscard]] bool memory_always_locked() noexcept;

}  // namespace vigil::platform::detail
