#include "vigil/can/sniffer.hpp"

#include <algorithm>

namespace vigil::can {

namespace detail {

namespace {
constexpr std::uint8_t key_bus(std::uint64_t k) noexcept {
  return static_cast<std::uint8_t>((k >> 40) & 0xFF);
}
}  // namespace

SnifferState::SnifferState(std::string name, const SnifferOptions& options)
    : name_(std::move(name)),
      node_map_(options.node_map),
      ids_(options.max_ids),
      nodes_(options.max_nodes) {}

SnifferState::~SnifferState() {
  // No I/O thread calls process() any more (the Sniffer is gone): everything can go.
  delete filter_.load(std::memory_order_acquire);
  for (const Retired& r : retired_) delete r.filter;
}

void SnifferState::set_filter(std::unique_ptr<const Filter> filter) {
  std::lock_guard lock(writer_mutex_);
  std::string text = filter ? filter->text() : std::string("true");
  // Accept-all is published as null: the I/O thread's fast path, with no guard at all.
  const Filter* next = (filter && !filter->accepts_all()) ? filter.release() : nullptr;
  // seq_cst exchange then seq_cst load: see process() for the other half of this handshake.
  const Filter* previous = filter_.exchange(next, std::memory_order_seq_cst);
  const std::uint64_t epoch = epoch_.load(std::memory_order_seq_cst);
  if (previous != nullptr) retired_.push_back({previous, epoch});
  filter_text_ = std::move(text);
  filter_changes_.fetch_add(1, std::memory_order_relaxed);  // counter only, orders nothing
  reclaim_locked();
}

std::size_t SnifferState::reclaim() {
  std::lock_guard lock(writer_mutex_);
  return reclaim_locked();
}

std::size_t SnifferState::reclaim_locked() {
  if (retired_.empty()) return 0;
  // Acquire: pairs with the I/O thread's release when it leaves the guard, so its last use of a
  // retired filter happens before the delete below.
  const std::uint64_t now = epoch_.load(std::memory_order_acquire);
  const std::size_t before = retired_.size();
  std::erase_if(retired_, [&](const Retired& r) {
    // Even at retirement: the I/O thread was outside any call, and its next call loads the new
    // pointer. Moved since: it has left the call that could hold the old one.
    if (r.epoch % 2 == 0 || now != r.epoch) {
      delete r.filter;
      return true;
    }
    return false;
  });
  return before - retired_.size();
}

std::size_t SnifferState::retired() const {
  std::lock_guard lock(writer_mutex_);
  return retired_.size();
}

std::string SnifferState::filter_text() const {
  std::lock_guard lock(writer_mutex_);
  return filter_text_;
}

SnifferTotals SnifferState::totals() const noexcept {
  SnifferTotals t;
  // Relaxed: independent counters; each is exact, the set is not a single snapshot.
  t.frames = frames_.load(std::memory_order_relaxed);
  t.tx = tx_.load(std::memory_order_relaxed);
  t.rx = t.frames >= t.tx ? t.frames - t.tx : 0;
  t.error_frames = error_frames_.load(std::memory_order_relaxed);
  t.remote_frames = remote_frames_.load(std::memory_order_relaxed);
  t.rejected = rejected_.load(std::memory_order_relaxed);
  t.accepted = accepted_.load(std::memory_order_relaxed);
  t.untracked_ids = untracked_ids_.load(std::memory_order_relaxed);
  t.untracked_nodes = untracked_nodes_.load(std::memory_order_relaxed);
  t.filter_changes = filter_changes_.load(std::memory_order_relaxed);
  return t;
}

void SnifferState::read_ids(std::vector<IdEntry>& out) const {
  ids_.for_each([&](std::uint64_t k, const IdCounter& s) {
    IdEntry e;
    e.bus = key_bus(k);
    e.id = static_cast<std::uint32_t>(k & 0xFFFFFFFFU);
    e.extended = ((k >> 32) & 1U) != 0;
    e.direction = ((k >> 33) & 1U) != 0 ? Direction::Tx : Direction::Rx;
    e.rtr = ((k >> 34) & 1U) != 0;
    e.error = ((k >> 35) & 1U) != 0;
    e.node = s.node;
    e.function = s.function;
    e.peer = s.peer;
    e.flags = s.flags;
    e.frames = s.frames.load(std::memory_order_relaxed);
    e.first_ns = s.first.load(std::memory_order_relaxed);
    e.last_ns = s.last.load(std::memory_order_relaxed);
    out.push_back(e);
  });
}

void SnifferState::read_nodes(std::vector<NodeEntry>& out) const {
  nodes_.for_each([&](std::uint64_t k, const NodeCounter& s) {
    NodeEntry e;
    e.bus = key_bus(k);
    e.node = static_cast<std::uint32_t>(k & 0xFFFFFFFFU);
    e.direction = ((k >> 32) & 1U) != 0 ? Direction::Tx : Direction::Rx;
    e.frames = s.frames.load(std::memory_order_relaxed);
    e.remote_frames = s.remote.load(std::memory_order_relaxed);
    e.first_ns = s.first.load(std::memory_order_relaxed);
    e.last_ns = s.last.load(std::memory_order_relaxed);
    out.push_back(e);
  });
}

}  // namespace detail

void CanRegistry::attach(std::uint32_t port_id, std::shared_ptr<detail::SnifferState> state) {
  std::lock_guard lock(mutex_);
  for (auto& [id, s] : states_) {
    if (id == port_id) {
      s = std::move(state);
      return;
    }
  }
  states_.emplace_back(port_id, std::move(state));
}

std::shared_ptr<detail::SnifferState> CanRegistry::find(std::uint32_t port_id) const {
  std::lock_guard lock(mutex_);
  for (const auto& [id, s] : states_) {
    if (id == port_id) return s;
  }
  return nullptr;
}

void CanRegistry::release(std::uint32_t port_id) {
  std::lock_guard lock(mutex_);
  std::erase_if(states_, [&](const auto& p) { return p.first == port_id; });
}

std::size_t CanRegistry::size() const {
  std::lock_guard lock(mutex_);
  return states_.size();
}

}  // namespace vigil::can
