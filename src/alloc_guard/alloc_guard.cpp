// vigil::alloc_guard: counts every heap allocation per thread by interposing the malloc family.
//
// Linked only by programs that opt in (target vigil::alloc_guard). The definitions below take
// precedence over glibc's for every call in the process, including operator new in libstdc++,
// and forward to glibc's __libc_* entry points. The only added work is one increment of an
// initial-exec thread-local counter, so a program that does not allocate pays nothing.
//
// Sanitizer builds replace malloc themselves; there this file compiles to nothing and
// allocation counting reports itself unavailable.
#include "vigil/platform/rt_loss.hpp"

#if !defined(VIGIL_ALLOC_GUARD_DISABLED)

#include <cerrno>
#include <cstddef>

// glibc's own allocator entry points, which the interposer forwards to.
// NOLINTBEGIN(bugprone-reserved-identifier)
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
void __libc_free(void*);
}

namespace {
inline void count() noexcept { ++vigil::platform::detail::tls_allocations; }

struct Registration {
  Registration() noexcept { vigil::platform::detail::alloc_guard_linked = true; }
} const registration;
}  // namespace

extern "C" {

void* malloc(std::size_t size) {
  count();
  return __libc_malloc(size);
}

void* calloc(std::size_t n, std::size_t size) {
  count();
  return __libc_calloc(n, size);
}

void* realloc(void* p, std::size_t size) {
  count();
  return __libc_realloc(p, size);
}

void free(void* p) { __libc_free(p); }

void* memalign(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}

void* aligned_alloc(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}

int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  count();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr && size != 0) return ENOMEM;
  *out = p;
  return 0;
}

void* valloc(std::size_t size) {
  count();
  return __libc_valloc(size);
}

void* pvalloc(std::size_t size) {
  count();
  return __libc_pvalloc(size);
}

}  // extern "C"

#endif
// NOLINTEND(bugprone-reserved-identifier)
