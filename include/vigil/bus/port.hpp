#pragma once
/// @file
/// `Port<Variant, N>`: the bounded, wait-free, single-producer single-consumer queue that carries a
/// component's messages to the supervisor.
///
/// Design: one producer (the component's thread) and one consumer (the supervisor thread).
/// The ring is boost::lockfree::spsc_queue with its capacity fixed at compile time, so the
/// storage lives inside the Port and push never allocates. When the ring is full the NEW message
/// is dropped and counted (the producer never pops). The consumer reads through the
/// type-erased `PortReader<Variant>` so that one supervisor drains ports of any capacity.
///
/// A port may instead send to a shared-memory ring that a `vigil supervise` daemon drains
/// (`attach_shm`, done by the Registry at join when it places ports in shared memory): the push
/// then goes there, with the same drop-and-count rule, and this process's supervisor sees an
/// empty port. One predictable branch per push decides.

#include <algorithm>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstddef>
#include <cstdint>

#include "vigil/assert.hpp"
#include "vigil/bus/shm_port.hpp"

namespace vigil::bus {

/// The consumer's view of a port (type-erased capacity). Supervisor side only.
template <class Variant>
class PortReader {
 public:
  virtual ~PortReader() = default;

  /// Moves up to `max` messages into `out`, oldest first; returns how many. Consumer only.
  /// Wait-free, no allocation.
  virtual std::size_t pop(Variant* out, std::size_t max) noexcept = 0;
  /// Messages waiting. Consumer only.
  [[nodiscard]] virtual std::size_t read_available() const noexcept = 0;
  /// Messages the port can hold.
  [[nodiscard]] virtual std::size_t capacity() const noexcept = 0;
  /// Hints the oldest waiting message into the caches, for a consumer that will pop from this
  /// port soon (the supervisor asks it of the next port while it handles the current one).
  /// Consumer only; wait-free, no allocation. The default does nothing.
  virtual void prefetch() const noexcept {}
  /// Messages dropped because the port was full. Any thread.
  [[nodiscard]] std::uint64_t dropped() const noexcept {
    return dropped_.load(std::memory_order_relaxed);
  }

 protected:
  // Written by the producer only; a relaxed load + store is enough (single writer) and avoids
  // a locked read-modify-write on the hot path.
  std::atomic<std::uint64_t> dropped_{0};
};

/// A component's port: `N` messages of type `Variant`.
template <class Variant, std::size_t N>
class Port final : public PortReader<Variant> {
  static_assert(N >= 1, "a Port needs a capacity of at least 1");
  static_assert(std::is_trivially_copyable_v<Variant>,
                "Port messages must be trivially copyable (use FixedString, not std::string)");

 public:
  /// Pushes `m`, or drops it and counts the drop when the port is full.
  /// RT-safe: wait-free, no allocation, no system call. Producer thread only.
  [[nodiscard]] [[gnu::always_inline]] bool try_push(const Variant& m) noexcept {
#ifndef NDEBUG
    ProducerGuard guard(producers_);
#endif
    if (shm_ != nullptr) [[unlikely]] {
      // Inline, as the in-process push below: a component in shared memory takes this branch
      // every cycle, and each call level cost it ~3 ns (docs/design/performance-history.md). A
      // drop is rare.
      if (shm_->push(m)) [[likely]]
        return true;
      shm_drop(m);
      return false;
    }
    if (queue_.push(m)) [[likely]]
      return true;
    this->dropped_.store(this->dropped_.load(std::memory_order_relaxed) + 1,
                         std::memory_order_relaxed);
    return false;
  }

  /// Pushes `m` if there is room; when full, returns false WITHOUT counting a drop, for a
  /// producer that keeps the message and retries later. RT-safe. Producer thread only.
  [[nodiscard]] bool try_push_or_keep(const Variant& m) noexcept {
#ifndef NDEBUG
    ProducerGuard guard(producers_);
#endif
    if (shm_ != nullptr) {
      if (shm_->push(m)) return true;
      shm_->keep(m);  // a daemon that drains meanwhile still learns it
      return false;
    }
    return queue_.push(m);
  }

  /// Sends every later push to shared-memory producer `p` (which must outlive the port's use)
  /// instead of the in-process ring; null goes back to it. Call once, before the first push.
  void attach_shm(bus::ShmProducer<Variant>* p) noexcept { shm_ = p; }
  /// The shared-memory producer this port sends to, or null.
  [[nodiscard]] bus::ShmProducer<Variant>* shm() const noexcept { return shm_; }

  std::size_t pop(Variant* out, std::size_t max) noexcept override {
    return shm_ != nullptr ? 0 : queue_.pop(out, max);
  }
  [[nodiscard]] std::size_t read_available() const noexcept override {
    return shm_ != nullptr ? 0 : queue_.read_available();
  }
  [[nodiscard]] std::size_t capacity() const noexcept override { return N; }
  void prefetch() const noexcept override {
    if (shm_ != nullptr) return;
    // Up to 8 messages (16 lines of 128-byte messages; past the ring's end is harmless: a hint).
    const std::size_t n = std::min<std::size_t>(queue_.read_available(), 8);
    if (n == 0) return;
    const auto* p = reinterpret_cast<const char*>(&queue_.front());
    for (std::size_t off = 0; off < n * sizeof(Variant); off += 64) __builtin_prefetch(p + off);
  }

 private:
  [[gnu::noinline]] void shm_drop(const Variant& m) noexcept {
    const std::uint64_t d = this->dropped_.load(std::memory_order_relaxed) + 1;
    this->dropped_.store(d, std::memory_order_relaxed);
    shm_->drop(m, d);
  }

#ifndef NDEBUG
  // Debug builds assert that only one thread pushes at a time (readerwriterqueue's
  // ReentrantGuard): two producers on one SPSC ring corrupt it silently.
  struct ProducerGuard {
    explicit ProducerGuard(std::atomic<int>& n) noexcept : n_(n) {
      VIGIL_ASSERT(n_.fetch_add(1, std::memory_order_relaxed) == 0,
                   "Port::try_push called from two threads at once (single producer only)");
    }
    ~ProducerGuard() { n_.fetch_sub(1, std::memory_order_relaxed); }
    std::atomic<int>& n_;
  };
  std::atomic<int> producers_{0};
#endif
  bus::ShmProducer<Variant>* shm_ = nullptr;
  // boost's compile-time ring reserves its spare slot itself: capacity<N> holds N (tested).
  boost::lockfree::spsc_queue<Variant, boost::lockfree::capacity<N>> queue_;
};

}  // namespace vigil::bus

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using bus::Port;
using bus::PortReader;
}  // namespace vigil
