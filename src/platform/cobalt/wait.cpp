// Cobalt wait/wake on a 32-bit word, without relaxing a primary-mode thread.
//
// Cobalt has no futex, and a Linux futex call would relax the caller (a mode switch on every
// trigger). Design: the word's address hashes to one of kBuckets buckets; each bucket has a Cobalt
// counting semaphore (sem_init_np with SEM_RAWCLOCK: absolute timeouts on Cobalt's
// CLOCK_MONOTONIC, the clock of now_ns()) and a count of registered waiters.
//   - wait_on registers, re-checks the word, then sleeps on the semaphore;
//   - wake_one posts one token per registered waiter that has none yet, and skips everything
//     (no system call) when nobody is registered.
// Registration and the word check are separated from the waker's store by sequentially consistent
// operations on both sides (a waiter's fetch_add, a waker's fence), so either the waker sees the
// waiter registered, or the waiter sees the new value: no lost wake-up. Waiters for different words
// that share a bucket all get a token, which for them is a spurious wake-up (allowed by the
// contract); tokens left by waiters that returned early are consumed by the next wait on that
// bucket, once each, so the spurious returns are bounded by the number of waiters.
//
// sem_wait is a "primary" Cobalt call (a relaxed caller returns to primary mode); sem_post is a
// "current" one, usable from any thread and with no system call when no thread sleeps on it.
// A thread that is not a Cobalt thread (std::thread, ...) gets EPERM from sem_wait; such threads
// wait on a Linux futex instead (counted apart so that wake_one calls futex only for them, and
// then relaxes a primary-mode waker once). A bucket's semaphore is created on first use; until it
// exists, that first call also takes the futex path.
#include "vigil/platform/wait.hpp"

#include "platform/cobalt/build_check.hpp"

#include <linux/futex.h>
#include <semaphore.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <ctime>

// Xenomai headers last: they define macros C++ headers must not see.
#include <cobalt/uapi/sem.h>
#include <cobalt/wrappers.h>

namespace vigil::platform {

namespace {

static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);

constexpr std::size_t kBuckets = 32;  // power of two
enum BucketState : int { kUninit = 0, kInitialising = 1, kReady = 2 };

struct alignas(64) Bucket {  // one cache line each: buckets are touched by unrelated threads
  std::atomic<int> state{kUninit};
  std::atomic<std::uint32_t> cobalt_waiters{0};
  std::atomic<std::uint32_t> linux_waiters{0};
  sem_t sem{};
};
constinit Bucket g_buckets[kBuckets];

// A thread that got EPERM from Cobalt once is not a Cobalt thread; it skips the semaphore.
thread_local bool tls_not_cobalt = false;

Bucket& bucket_for(const void* address) noexcept {
  // Fibonacci hashing of the address without its low (alignment) bits.
  const auto a = reinterpret_cast<std::uintptr_t>(address) >> 2;
  return g_buckets[(a * 0x9E3779B97F4A7C15ull) >> (64 - 5)];
}
static_assert(kBuckets == 1u << 5, "the hash above takes 5 bits");

auto* word_address(const std::atomic<std::uint32_t>& word) noexcept {
  return reinterpret_cast<std::uint32_t*>(const_cast<std::atomic<std::uint32_t>*>(&word));
}

timespec to_timespec(Nanos ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / kNanosPerSecond);
  ts.tv_nsec = static_cast<long>(ns % kNanosPerSecond);
  return ts;
}

// True when the bucket's semaphore exists. The first caller creates it (a "current"-mode Cobalt
// system call, no mode switch); a caller that finds it being created does not spin (a
// higher-priority spinner could starve the creator on its CPU) but takes the futex path once.
bool ensure_ready(Bucket& b) noexcept {
  int s = b.state.load(std::memory_order_acquire);
  if (s == kReady) return true;
  if (s == kUninit &&
      b.state.compare_exchange_strong(s, kInitialising, std::memory_order_acq_rel)) {
    // No SEM_FIFO: sleepers queue by priority. SEM_RAWCLOCK: timeouts on CLOCK_MONOTONIC.
    const bool ok = sem_init_np(&b.sem, SEM_RAWCLOCK, 0) == 0;
    // On failure (process not bound to Cobalt yet, core out of memory) a later call retries.
    b.state.store(ok ? kReady : kUninit, std::memory_order_release);
    return ok;
  }
  return false;
}

// Returns false when the caller turned out not to be a Cobalt thread.
bool wait_cobalt(Bucket& b, const std::atomic<std::uint32_t>& word, std::uint32_t expected,
                 Nanos deadline_ns) noexcept {
  b.cobalt_waiters.fetch_add(1, std::memory_order_seq_cst);
  if (word.load(std::memory_order_seq_cst) != expected) {
    b.cobalt_waiters.fetch_sub(1, std::memory_order_relaxed);
    return true;
  }
  int rc = 0;
  if (deadline_ns > 0) {
    const timespec ts = to_timespec(deadline_ns);
    rc = __RT(sem_timedwait)(&b.sem, &ts);
  } else {
    rc = __RT(sem_wait)(&b.sem);
  }
  // -1/errno convention here (unlike pthread_*). ETIMEDOUT, EINTR (a SIGDEBUG handler ran) and
  // EINVAL all return to the caller, which re-checks its condition as after any wake-up.
  const bool not_cobalt = rc != 0 && errno == EPERM;
  b.cobalt_waiters.fetch_sub(1, std::memory_order_relaxed);
  return !not_cobalt;
}

void wait_linux(Bucket& b, const std::atomic<std::uint32_t>& word, std::uint32_t expected,
                Nanos deadline_ns) noexcept {
  b.linux_waiters.fetch_add(1, std::memory_order_seq_cst);
  timespec rel{};
  timespec* timeout = nullptr;
  bool expired = false;
  if (deadline_ns > 0) {
    // Relative timeout: the deadline is on Cobalt's clock, which with I-pipe kernels is not
    // Linux's CLOCK_MONOTONIC; a duration means the same on both.
    const Nanos left = deadline_ns - now_ns();
    expired = left <= 0;
    rel = to_timespec(left);
    timeout = &rel;
  }
  // The kernel re-checks `word == expected` atomically with going to sleep.
  if (!expired) {
    ::syscall(SYS_futex, word_address(word), FUTEX_WAIT_PRIVATE, expected, timeout, nullptr, 0);
  }
  b.linux_waiters.fetch_sub(1, std::memory_order_relaxed);
}

}  // namespace

void wait_on(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
             Nanos deadline_ns) noexcept {
  Bucket& b = bucket_for(&word);
  if (!tls_not_cobalt && ensure_ready(b)) {
    if (wait_cobalt(b, word, expected, deadline_ns)) return;
    tls_not_cobalt = true;
  }
  wait_linux(b, word, expected, deadline_ns);
}

void wake_one(const std::atomic<std::uint32_t>& word) noexcept {
  Bucket& b = bucket_for(&word);
  // Pairs with the waiters' seq_cst registration (see the design note at the top).
  std::atomic_thread_fence(std::memory_order_seq_cst);
  const auto cobalt_waiters = b.cobalt_waiters.load(std::memory_order_seq_cst);
  if (cobalt_waiters > 0) {
    // A registered Cobalt waiter implies a ready semaphore (it registers after ensure_ready).
    // sem_getvalue reports the tokens not yet taken (0 while threads sleep on it): post the
    // missing ones only, so tokens never pile up beyond the number of waiters.
    int tokens = 0;
    __RT(sem_getvalue)(&b.sem, &tokens);
    for (auto i = static_cast<std::uint32_t>(std::max(tokens, 0)); i < cobalt_waiters; ++i) {
      __RT(sem_post)(&b.sem);
    }
  }
  if (b.linux_waiters.load(std::memory_order_seq_cst) > 0) {
    ::syscall(SYS_futex, word_address(word), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
  }
}

}  // namespace vigil::platform
