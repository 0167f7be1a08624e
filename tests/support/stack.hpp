#pragma once
// The calling thread's stack size as glibc's pthread_getattr_np reports it: an independent reader
// for tests of the stack sizes vigil gives its threads.

#include <pthread.h>

#include <cstddef>

namespace vigil::test {

/// Stack size of the calling thread, in bytes; 0 when it cannot be read.
inline std::size_t current_stack_bytes() {
  pthread_attr_t attr;
  if (pthread_getattr_np(pthread_self(), &attr) != 0) return 0;
  std::size_t size = 0;
  if (pthread_attr_getstacksize(&attr, &size) != 0) size = 0;
  pthread_attr_destroy(&attr);
  return size;
}

/// The stack a thread gets from pthread_create without a size (glibc: `ulimit -s`, or 2 MiB when
/// unlimited).
inline std::size_t system_default_stack_bytes() {
  pthread_attr_t attr;
  if (pthread_getattr_default_np(&attr) != 0) return 0;
  std::size_t size = 0;
  if (pthread_attr_getstacksize(&attr, &size) != 0) size = 0;
  pthread_attr_destroy(&attr);
  return size;
}

/// True when a thread that asked for `requested` bytes of stack got `got`. glibc gives a new thread
/// the cached stack of a thread that ended when that stack is at least as large and at most four
/// times as large as asked (nptl's get_cached_stack), so a test that ran threads before sees any
/// size in [requested, 4 x requested]; a size outside says the request was ignored.
///
/// ThreadSanitizer's pthread_create raises every stack below its own minimum (900 KiB with GCC
/// 12's libtsan, measured) to that minimum, so under TSan a small request may get up to 1 MiB.
inline bool stack_serves(std::size_t got, std::size_t requested) {
#if defined(__SANITIZE_THREAD__)
  constexpr std::size_t kTsanMinimumStack = 1024 * 1024;
  const std::size_t most = 4 * requested > kTsanMinimumStack ? 4 * requested : kTsanMinimumStack;
#else
  const std::size_t most = 4 * requested;
#endif
  return got >= requested && got <= most;
}

}  // namespace vigil::test
