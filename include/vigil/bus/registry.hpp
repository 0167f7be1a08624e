#pragma once
/// @file
/// `Registry<Variant>`: where components' ports meet the supervisor. It replaces the original's
/// process-wide singleton with an explicit object (and `default_registry()` for the one-line use).
///
/// Design: components join and leave at any time from any non-RT thread; joining creates the
/// component's port (the only allocation) and returns a `Membership` that the component keeps.
/// The supervisor polls `generation()` (one atomic load per cycle) and copies the entry list only
/// when it changed. Entries are shared: a component that leaves marks its entry closed, and the
/// supervisor drains what is left before forgetting it. No start order is required: ports
/// created before the supervisor exists are simply found on its first cycle.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "vigil/assert.hpp"
#include "vigil/bus/port.hpp"
#include "vigil/bus/shm_session.hpp"

namespace vigil::bus {

/// One registered port. Shared by the registry, the member and the supervisor.
template <class Variant>
struct RegistryEntry {
  std::uint32_t id = 0;  ///< unique for the registry's lifetime, never reused
  std::string name;
  std::shared_ptr<PortReader<Variant>> port;
  std::atomic<bool> closed{false};  ///< set when the member left; drain, then forget
  /// Messages the member left behind when it could no longer push (e.g. its final totals when
  /// the port was full). Written before `closed` is set; visited after the port is drained.
  std::vector<Variant> last_words;
  /// Set by the supervisor once it has drained and forgotten the entry.
  std::atomic<bool> finished{false};
  /// Set when the port lives in shared memory: a `vigil supervise` daemon drains it, and this
  /// registry's supervisor never sees the entry.
  std::shared_ptr<bus::ShmPort<Variant>> shm;
  /// Where the entry sits in its registry's list of members (the registry's, under its lock):
  /// leaving is O(1), not a search of every member.
  std::size_t slot = 0;
};

template <class Variant>
class Registry;

/// A component's membership: owns the producer end of its port; leaves on destruction.
/// Move-only. `port()` is RT-safe to use from the component's thread.
template <class Variant, std::size_t N>
class Membership {
 public:
  Membership() = default;
  Membership(Membership&& o) noexcept
      : registry_(std::exchange(o.registry_, nullptr)),
        entry_(std::move(o.entry_)),
        port_(std::exchange(o.port_, nullptr)) {}
  Membership& operator=(Membership&& o) noexcept {
    if (this != &o) {
      leave();
      registry_ = std::exchange(o.registry_, nullptr);
      entry_ = std::move(o.entry_);
      port_ = std::exchange(o.port_, nullptr);
    }
    return *this;
  }
  Membership(const Membership&) = delete;
  Membership& operator=(const Membership&) = delete;
  ~Membership() { leave(); }

  /// The producer end. Null for a default-constructed membership.
  [[nodiscard]] Port<Variant, N>* port() const noexcept { return port_; }
  [[nodiscard]] std::uint32_t id() const noexcept { return entry_ ? entry_->id : 0; }
  [[nodiscard]] bool joined() const noexcept { return entry_ != nullptr; }

  /// Leaves the registry (idempotent). Messages already pushed are still drained, then
  /// `last_words` are visited. Not RT-safe.
  void leave(std::vector<Variant> last_words = {});

 private:
  friend class Registry<Variant>;
  Registry<Variant>* registry_ = nullptr;
  std::shared_ptr<RegistryEntry<Variant>> entry_;
  Port<Variant, N>* port_ = nullptr;
};

/// The set of ports a supervisor drains. Thread-safe; none of it is RT-safe (it allocates and
/// locks), and none of it is called by the RT side after joining.
template <class Variant>
class Registry {
 public:
  using Entry = RegistryEntry<Variant>;
  using ShmPortsType = bus::ShmPorts<Variant>;

  Registry() = default;
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  /// Creates a port of capacity N for component `name` and registers it. Names need not be
  /// unique (ids are). Not RT-safe.
  template <std::size_t N>
  Membership<Variant, N> join(const std::string& name) {
    auto port = std::make_shared<Port<Variant, N>>();
    auto entry = std::make_shared<Entry>();
    entry->name = name;
    entry->port = port;
    Membership<Variant, N> m;
    m.registry_ = this;
    m.port_ = port.get();
    std::shared_ptr<ShmPortsType> shm;
    {
      std::lock_guard lock(mutex_);
      shm = shm_;
    }
    if (shm) {
      entry->shm = shm->open(entry->name, N);
      if (entry->shm) port->attach_shm(&entry->shm->producer());
    }
    {
      std::lock_guard lock(mutex_);
      entry->id = next_id_++;
      if (!entry->shm) {
        entry->slot = entries_.size();
        entries_.push_back(entry);
        generation_.fetch_add(1, std::memory_order_release);
      }
    }
    m.entry_ = std::move(entry);
    return m;
  }

  /// Changes whenever a member joins or leaves. One atomic load: the supervisor's fast check.
  [[nodiscard]] std::uint64_t generation() const noexcept {
    return generation_.load(std::memory_order_acquire);
  }

  /// Copies the current entries, and those that left since the last call, into `out`
  /// (ordered by id; O(n log n) for n entries: the member list itself is kept in no order, so
  /// that leaving is O(1)). Takes the lock briefly. Meant for the registry's one supervisor: a
  /// member that joins and leaves between two supervisor cycles is still handed over once, so its
  /// messages are drained. At most kMaxDeparted departed entries are kept for a supervisor that
  /// has not collected yet (the oldest go first).
  void collect(std::vector<std::shared_ptr<Entry>>& out) {
    std::lock_guard lock(mutex_);
    out.assign(entries_.begin(), entries_.end());
    out.insert(out.end(), departed_.begin(), departed_.end());
    departed_.clear();
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a->id < b->id; });
  }

  static constexpr std::size_t kMaxDeparted = 4096;

  /// Number of current members.
  [[nodiscard]] std::size_t size() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
  }

  /// Places the ports of components that join from now on in shared memory (null: in this
  /// process again). Components that joined before keep their ports. Not RT-safe.
  void place_in_shared_memory(std::shared_ptr<ShmPortsType> ports) {
    std::lock_guard lock(mutex_);
    shm_ = std::move(ports);
  }
  /// Where ports are placed now: null for in-process.
  [[nodiscard]] std::shared_ptr<ShmPortsType> shared_memory() const {
    std::lock_guard lock(mutex_);
    return shm_;
  }

  /// Called by Membership::leave.
  void remove(const std::shared_ptr<Entry>& entry, std::vector<Variant> last_words) {
    if (entry->shm) {
      // Its last words go to the segment (or its mailboxes), then the daemon drains and removes
      // it; the port is not pushed to again.
      entry->shm->set_dropped(entry->port->dropped());
      entry->shm->close(last_words);
      entry->closed.store(true, std::memory_order_release);
      entry->finished.store(true, std::memory_order_relaxed);
      return;
    }
    std::lock_guard lock(mutex_);
    entry->last_words = std::move(last_words);
    // O(1): the last member takes the leaving one's place (collect() sorts by id).
    const std::size_t i = entry->slot;
    VIGIL_ASSERT(i < entries_.size() && entries_[i] == entry,
                 "Registry::remove: the entry is not a member of this registry");
    if (i + 1 != entries_.size()) {
      entries_[i] = std::move(entries_.back());
      entries_[i]->slot = i;
    }
    entries_.pop_back();
    if (departed_.size() == kMaxDeparted) departed_.pop_front();
    departed_.push_back(entry);
    generation_.fetch_add(1, std::memory_order_release);
    // Last, under the lock: a supervisor that sees `closed` finds the entry among the departed
    // at its next collect() at the latest.
    entry->closed.store(true, std::memory_order_release);
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Entry>> entries_;  // in no order; each entry knows its slot
  std::deque<std::shared_ptr<Entry>> departed_;
  std::uint32_t next_id_ = 1;
  std::atomic<std::uint64_t> generation_{0};
  std::shared_ptr<ShmPortsType> shm_;
};

template <class Variant, std::size_t N>
void Membership<Variant, N>::leave(std::vector<Variant> last_words) {
  if (registry_ != nullptr && entry_) registry_->remove(entry_, std::move(last_words));
  registry_ = nullptr;
  entry_.reset();
  port_ = nullptr;
}

}  // namespace vigil::bus

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using bus::Registry;
}  // namespace vigil
