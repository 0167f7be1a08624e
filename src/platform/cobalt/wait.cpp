// Cobalt wait/wake on a 32-bit word, without relaxing a primary-mode thread.
//
// Cobalt has no futex, and a Linux futex call would relax the caller: a mode switch on every
// trigger. Design (addressed wake-ups, so that no waiter can take another's):
//   - A Cobalt thread that waits gets a record from a fixed pool the first time (released by a
//     pthread key destructor when it exits, then reused): the address it waits on, and its own
//     Cobalt semaphore (sem_init_np, SEM_RAWCLOCK: absolute timeouts on Cobalt's CLOCK_MONOTONIC,
//     the clock of now_ns()). Only that thread ever waits on that semaphore.
//   - wait_on publishes the address in its record, re-checks the word, then sleeps on its
//     semaphore. wake_one scans the records in use and posts the semaphore of each one that waits
//     on the word, only if it holds no token yet (so at most one stale token per record: a
//     bounded number of spurious wake-ups, which the contract allows).
//   - The waiter's publication and the waker's store to the word are ordered by sequentially
//     consistent operations on both sides (the waiter's seq_cst store and load, the waker's fence
//     and loads): either the waker sees the waiter registered, or the waiter sees the new value.
//     No lost wake-up.
// sem_wait is a "primary" Cobalt call (a relaxed caller returns to primary mode); sem_post and
// sem_getvalue are usable from any thread, Cobalt or not: sem_post makes a "current"-mode Cobalt
// system call only when the thread sleeps, sem_getvalue none.
// Threads that are not Cobalt threads (std::thread, ...) cannot sleep on a Cobalt semaphore
// (EPERM); they, and Cobalt threads when the pool is exhausted, wait on a Linux futex. A waker
// calls futex only while such a waiter exists (and then relaxes once if it runs in primary mode).
// Cost of wake_one: one fence, one load per record ever used (the threads that waited), and a
// system call only when a thread sleeps on the word. Not a lock anywhere.
#include "vigil/platform/wait.hpp"

#include "platform/cobalt/build_check.hpp"

#include <pthread.h>
#include <semaphore.h>

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <ctime>

#include "platform/posix/futex.hpp"
#include "platform/posix/timespec.hpp"

// Xenomai headers last: they define macros C++ headers must not see.
#include <cobalt/sys/cobalt.h>
#include <cobalt/uapi/sem.h>
#include <cobalt/wrappers.h>

namespace vigil::platform {

namespace {

using detail::to_timespec;

// More Cobalt threads than this waiting at the same time still work, through the futex path.
constexpr std::uint32_t kRecords = 64;

struct alignas(64) Record {  // one cache line each: records are written by unrelated threads
  std::atomic<bool> in_use{false};
  std::atomic<bool> sem_ready{false};  // the semaphore outlives its threads; created once
  std::atomic<const void*> waiting_on{nullptr};
  sem_t sem{};
};
constinit Record g_records[kRecords];
// Records [0, g_records_used) have been handed out at least once; wake_one scans only those.
constinit std::atomic<std::uint32_t> g_records_used{0};
// Threads sleeping (or about to) on a Linux futex; wake_one calls futex only when this is > 0.
constinit std::atomic<std::uint32_t> g_futex_waiters{0};

enum class Kind : std::uint8_t { Unknown, Cobalt, Linux };
thread_local Kind tls_kind = Kind::Unknown;
thread_local Record* tls_record = nullptr;

void release_record(void* record) {
  auto* r = static_cast<Record*>(record);
  r->waiting_on.store(nullptr, std::memory_order_relaxed);
  r->in_use.store(false, std::memory_order_release);
}

pthread_key_t record_key() noexcept {
  // A pthread key destructor (not a thread_local with a destructor, whose registration may
  // allocate) gives the record back when the thread exits. Keys below 32 need no allocation.
  static const pthread_key_t key = [] {
    pthread_key_t k{};
    pthread_key_create(&k, &release_record);
    return k;
  }();
  return key;
}

Record* claim_record() noexcept {
  for (std::uint32_t i = 0; i < kRecords; ++i) {
    Record& r = g_records[i];
    bool expected = false;
    if (!r.in_use.compare_exchange_strong(expected, true, std::memory_order_acq_rel)) continue;
    if (!r.sem_ready.load(std::memory_order_acquire)) {
      // No SEM_FIFO: not needed, one thread per semaphore. A "current"-mode Cobalt call.
      if (sem_init_np(&r.sem, SEM_RAWCLOCK, 0) != 0) {
        r.in_use.store(false, std::memory_order_release);
        return nullptr;
      }
      r.sem_ready.store(true, std::memory_order_release);
    } else {
      // A token left for the previous owner would only be a spurious wake-up; drop it anyway.
      while (__RT(sem_trywait)(&r.sem) == 0) {
      }
    }
    std::uint32_t used = g_records_used.load(std::memory_order_relaxed);
    while (used < i + 1 && !g_records_used.compare_exchange_weak(used, i + 1)) {
    }
    pthread_setspecific(record_key(), &r);
    return &r;
  }
  return nullptr;
}

Kind this_thread_kind() noexcept {
  if (tls_kind == Kind::Unknown) {
    // A "current"-mode Cobalt system call: no mode switch; -ESRCH for a thread Cobalt does not
    // know.
    if (cobalt_thread_pid(pthread_self()) > 0) tls_record = claim_record();
    tls_kind = tls_record != nullptr ? Kind::Cobalt : Kind::Linux;
  }
  return tls_kind;
}

void wait_cobalt(Record& r, const std::atomic<std::uint32_t>& word, std::uint32_t expected,
                 Nanos deadline_ns) noexcept {
  r.waiting_on.store(&word, std::memory_order_seq_cst);
  if (word.load(std::memory_order_seq_cst) == expected) {
    // -1/errno convention here (unlike pthread_*). ETIMEDOUT, EINTR (a SIGDEBUG handler ran)
    // and EINVAL all return to the caller, which re-checks its condition as after any wake-up.
    if (deadline_ns > 0) {
      const timespec ts = to_timespec(deadline_ns);
      __RT(sem_timedwait)(&r.sem, &ts);
    } else {
      __RT(sem_wait)(&r.sem);
    }
  }
  r.waiting_on.store(nullptr, std::memory_order_relaxed);
}

void wait_linux(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
                Nanos deadline_ns) noexcept {
  g_futex_waiters.fetch_add(1, std::memory_order_seq_cst);
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
  if (!expired) detail::futex_wait_for(word, expected, timeout);
  g_futex_waiters.fetch_sub(1, std::memory_order_relaxed);
}

}  // namespace

void wait_on(const std::atomic<std::uint32_t>& word, std::uint32_t expected,
             Nanos deadline_ns) noexcept {
  if (this_thread_kind() == Kind::Cobalt) {
    wait_cobalt(*tls_record, word, expected, deadline_ns);
  } else {
    wait_linux(word, expected, deadline_ns);
  }
}

void wake_one(const std::atomic<std::uint32_t>& word) noexcept {
  // Pairs with the waiters' seq_cst registration (see the design note at the top).
  std::atomic_thread_fence(std::memory_order_seq_cst);
  const std::uint32_t used = g_records_used.load(std::memory_order_seq_cst);
  for (std::uint32_t i = 0; i < used; ++i) {
    Record& r = g_records[i];
    if (r.waiting_on.load(std::memory_order_seq_cst) != &word) continue;
    // 0 when the owner sleeps or no token is pending (Cobalt reports no negative values
    // without SEM_REPORT): post only then, so that at most one token waits in a record.
    int tokens = 0;
    if (__RT(sem_getvalue)(&r.sem, &tokens) == 0 && tokens <= 0) __RT(sem_post)(&r.sem);
  }
  if (g_futex_waiters.load(std::memory_order_seq_cst) > 0) {
    detail::futex_wake_one(word);
  }
}

}  // namespace vigil::platform
