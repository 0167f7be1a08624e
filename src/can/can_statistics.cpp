#include "vigil/can/can_statistics.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "vigil/supervisor/histogram.hpp"

namespace vigil::can {

bool GroupSpec::contains(std::uint8_t bus_index, std::uint32_t node) const noexcept {
  if (bus && *bus != bus_index) return false;
  if (std::find(nodes.begin(), nodes.end(), node) != nodes.end()) return true;
  return std::any_of(node_ranges.begin(), node_ranges.end(),
                     [&](const auto& r) { return node >= r.first && node <= r.second; });
}

const NodeStats* CanSnapshot::find_node(std::uint8_t bus, std::uint32_t node,
                                        Direction d) const noexcept {
  const auto key = [](const NodeStats& n) {
    return std::make_tuple(n.bus, n.node, static_cast<int>(n.direction));
  };
  const auto want = std::make_tuple(bus, node, static_cast<int>(d));
  const auto it = std::lower_bound(nodes.begin(), nodes.end(), want,
                                   [&](const NodeStats& n, const auto& w) { return key(n) < w; });
  return it != nodes.end() && key(*it) == want ? &*it : nullptr;
}

const IdStats* CanSnapshot::find_id(std::uint8_t bus, std::uint32_t id, bool extended, Direction d,
                                    bool rtr) const noexcept {
  const auto key = [](const IdStats& s) {
    return std::make_tuple(s.bus, s.id, s.extended, static_cast<int>(s.direction), s.error, s.rtr);
  };
  const auto want = std::make_tuple(bus, id, extended, static_cast<int>(d), false, rtr);
  const auto it = std::lower_bound(ids.begin(), ids.end(), want,
                                   [&](const IdStats& s, const auto& w) { return key(s) < w; });
  return it != ids.end() && key(*it) == want ? &*it : nullptr;
}

StatsSummary exact_summary(std::vector<Nanos>& samples) {
  StatsSummary s;
  if (samples.empty()) return s;
  const auto n = static_cast<std::uint64_t>(samples.size());
  s.count = n;
  long double sum = 0;
  Nanos lo = samples.front();
  Nanos hi = samples.front();
  for (const Nanos v : samples) {
    sum += static_cast<long double>(v);
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  s.min = lo;
  s.max = hi;
  s.mean = static_cast<double>(sum / static_cast<long double>(n));
  // The four ranks by selection, not a full sort: each nth_element leaves every sample after
  // its rank >= the sample at it, so the next (higher) rank is selected from the rest alone
  // (about 1.6 n steps in all instead of n log n).
  auto from = samples.begin();
  const auto at = [&](double q) {
    const auto k = static_cast<std::ptrdiff_t>(vigil::supervisor::detail::nearest_rank(q, n) - 1);
    const auto kth = samples.begin() + k;
    if (kth >= from) {
      std::nth_element(from, kth, samples.end());
      from = kth + 1;
    }
    return *kth;
  };
  s.p50 = at(0.5);
  s.p90 = at(0.9);
  s.p99 = at(0.99);
  s.p999 = at(0.999);
  return s;
}

namespace {

// What one sniffer's table says about a key.
struct Contribution {
  std::uint32_t port = 0;
  std::uint64_t frames = 0;
  Nanos first = 0;
  Nanos last = 0;
};

void contribute(std::vector<Contribution>& from, std::uint32_t port, std::uint64_t frames,
                Nanos first, Nanos last) {
  for (Contribution& c : from) {
    if (c.port == port) {
      c.frames = frames;
      c.first = first;
      c.last = last;
      return;
    }
  }
  from.push_back({port, frames, first, last});
}

struct Counted {
  std::uint64_t frames = 0;
  Nanos first = 0;
  Nanos last = 0;
  bool any = false;
};

Counted sum(const std::vector<Contribution>& from) {
  Counted c;
  for (const Contribution& x : from) {
    if (x.frames == 0) continue;
    c.first = c.any ? std::min(c.first, x.first) : x.first;
    c.last = c.any ? std::max(c.last, x.last) : x.last;
    c.frames += x.frames;
    c.any = true;
  }
  return c;
}

// Timing of one key, fed by records: histograms (live) or every gap (exact mode). Live, the
// histograms are CompactRunningStats (the buckets of the seen range only: a few hundred bytes a
// distribution instead of RunningStats' 9 KB; the same quantiles).
struct Timing {
  std::uint64_t records = 0;
  Nanos first_record = 0;
  Nanos last_record = 0;
  bool live = true;
  supervisor::CompactRunningStats io;   // live mode
  supervisor::CompactRunningStats gap;  // live mode
  supervisor::ScalarStats io_exact;     // exact mode
  supervisor::ScalarStats gap_exact;    // exact mode
  std::vector<Nanos> gaps;              // exact mode: every gap

  void init(bool exact, double weight) {
    live = !exact;
    static_cast<void>(io.set_ewma_weight(weight));
    static_cast<void>(gap.set_ewma_weight(weight));
    static_cast<void>(io_exact.set_ewma_weight(weight));
    static_cast<void>(gap_exact.set_ewma_weight(weight));
  }

  void add(const FrameRecord& r, Nanos gap_ns) {
    if (records == 0) first_record = r.time_ns;
    ++records;
    last_record = std::max(last_record, r.time_ns);
    if (live) {
      io.add(r.io_ns);
      if (gap_ns >= 0) gap.add(gap_ns);
      return;
    }
    io_exact.add(r.io_ns);
    if (gap_ns >= 0) {
      gap_exact.add(gap_ns);
      gaps.push_back(gap_ns);
    }
  }

  [[nodiscard]] StatsSummary io_summary() const { return live ? io.summary() : io_exact.summary(); }

  [[nodiscard]] StatsSummary gap_summary(bool& is_exact) {
    is_exact = false;
    if (live) return gap.summary();
    StatsSummary s = gap_exact.summary();
    if (!gaps.empty()) {
      const StatsSummary e = exact_summary(gaps);
      s.p50 = e.p50;
      s.p90 = e.p90;
      s.p99 = e.p99;
      s.p999 = e.p999;
      is_exact = true;
    }
    return s;
  }
};

// The constant description of an id key.
struct IdKey {
  std::uint8_t bus = 0;
  std::uint32_t id = 0;
  bool extended = false;
  bool rtr = false;
  bool error = false;
  Direction direction = Direction::Rx;
  std::uint32_t node = 0;
  std::uint32_t function = 0;
  std::uint32_t peer = kNoNode;
  std::uint8_t flags = 0;
};

struct IdAccumulator {
  IdKey key;
  std::vector<Contribution> from;
  Timing timing;
  std::uint8_t last_length = 0;
  std::array<std::uint8_t, 8> last_data{};
};

// The constant description of a node key.
struct NodeKey {
  std::uint8_t bus = 0;
  std::uint32_t node = 0;
  Direction direction = Direction::Rx;
};

struct NodeAccumulator {
  NodeKey key;
  std::vector<Contribution> from;
  std::vector<std::pair<std::uint32_t, std::uint64_t>> remote;  // per sniffer: remote frames
  Timing timing;
};

struct SnifferSlot {
  SnifferInfo info;
  std::shared_ptr<detail::SnifferState> state;
  NodeMapKind node_map = NodeMapKind::Identity;  // its mapping, for the protocol tracker
};

bool is_tx(Direction d) { return d == Direction::Tx; }

void add_totals(SnifferTotals& a, const SnifferTotals& b) {
  a.frames += b.frames;
  a.rx += b.rx;
  a.tx += b.tx;
  a.error_frames += b.error_frames;
  a.remote_frames += b.remote_frames;
  a.rejected += b.rejected;
  a.accepted += b.accepted;
  a.untracked_ids += b.untracked_ids;
  a.untracked_nodes += b.untracked_nodes;
  a.dropped += b.dropped;
  a.filter_changes += b.filter_changes;
}

// Accumulators by 64-bit key, at most `max` of them; a one-entry cache for runs of one key.
template <class Acc>
class KeyedAccumulators {
 public:
  explicit KeyedAccumulators(std::size_t max) : max_(max) {}

  // The accumulator of `key`, made by `make()` when new; null when the map is full.
  template <class Make>
  Acc* find_or_make(std::uint64_t key, Make&& make) {
    if (key == cached_key_ && cached_ != nullptr) return cached_;
    auto it = map_.find(key);
    if (it == map_.end()) {
      if (map_.size() >= max_) return nullptr;
      it = map_.emplace(key, make()).first;
    }
    cached_key_ = key;
    cached_ = it->second.get();
    return cached_;
  }

  [[nodiscard]] std::size_t size() const noexcept { return map_.size(); }
  [[nodiscard]] std::size_t max() const noexcept { return max_; }
  template <class F>
  void for_each(F&& f) {
    for (auto& [key, p] : map_) f(key, *p);
  }

 private:
  std::size_t max_;
  std::unordered_map<std::uint64_t, std::unique_ptr<Acc>> map_;
  std::uint64_t cached_key_ = 0;
  Acc* cached_ = nullptr;
};

std::uint64_t key_of(const IdKey& k) {
  return detail::id_key(k.bus, k.id, k.extended, is_tx(k.direction), k.rtr, k.error);
}
std::uint64_t key_of(const NodeKey& k) {
  return detail::node_key(k.bus, k.node, is_tx(k.direction));
}

}  // namespace

struct CanAggregator::Impl {
  CanRegistry& registry;
  CanAggregatorOptions options;

  mutable std::mutex mutex;           // guards everything below
  std::vector<SnifferSlot> sniffers;  // by port id
  KeyedAccumulators<IdAccumulator> ids;
  KeyedAccumulators<NodeAccumulator> nodes;
  std::uint64_t records = 0;
  std::uint64_t unaggregated_id_records = 0;
  std::uint64_t unaggregated_node_records = 0;
  std::uint64_t cycles = 0;
  std::uint64_t error_records = 0;
  ProtocolTracker protocol;

  // The cycle hook (set before the supervisor starts) and the wake-up it asked for.
  std::function<void(const supervisor::DrainCycle&)> cycle_hook;
  std::atomic<Nanos> wake_at{std::numeric_limits<Nanos>::max()};
  std::atomic<std::uint64_t> hook_failures{0};

  // Supervisor thread only.
  SnifferSlot* current = nullptr;
  std::vector<IdEntry> id_scratch;
  std::vector<NodeEntry> node_scratch;

  Impl(CanRegistry& r, CanAggregatorOptions o)
      : registry(r),
        options(std::move(o)),
        ids(options.max_ids),
        nodes(options.max_nodes),
        protocol(options.protocol) {}

  SnifferSlot* slot_of(std::uint32_t port) {
    for (SnifferSlot& s : sniffers) {
      if (s.info.port_id == port) return &s;
    }
    return nullptr;
  }

  IdAccumulator* id_acc(const IdKey& k) {
    return ids.find_or_make(key_of(k), [&] {
      auto p = std::make_unique<IdAccumulator>();
      p->key = k;
      p->timing.init(options.exact_percentiles, options.ewma_weight);
      return p;
    });
  }

  NodeAccumulator* node_acc(const NodeKey& k) {
    return nodes.find_or_make(key_of(k), [&] {
      auto p = std::make_unique<NodeAccumulator>();
      p->key = k;
      p->timing.init(options.exact_percentiles, options.ewma_weight);
      return p;
    });
  }

  // Reads one sniffer's tables and counters into the statistics (lock held).
  void read_tables(SnifferSlot& s) {
    if (!s.state) s.state = registry.find(s.info.port_id);
    if (!s.state) return;
    detail::SnifferState& st = *s.state;
    const std::uint32_t port = s.info.port_id;
    id_scratch.clear();
    st.read_ids(id_scratch);
    for (const IdEntry& e : id_scratch) {
      const IdKey k{e.bus,       e.id,   e.extended, e.rtr,  e.error,
                    e.direction, e.node, e.function, e.peer, e.flags};
      IdAccumulator* a = id_acc(k);
      if (a == nullptr) continue;
      a->key = k;  // the table is authoritative (a record may have made the key first)
      contribute(a->from, port, e.frames, e.first_ns, e.last_ns);
    }
    node_scratch.clear();
    st.read_nodes(node_scratch);
    for (const NodeEntry& e : node_scratch) {
      NodeAccumulator* a = node_acc(NodeKey{e.bus, e.node, e.direction});
      if (a == nullptr) continue;
      contribute(a->from, port, e.frames, e.first_ns, e.last_ns);
      auto it = std::find_if(a->remote.begin(), a->remote.end(),
                             [&](const auto& r) { return r.first == port; });
      if (it == a->remote.end()) {
        a->remote.emplace_back(port, e.remote_frames);
      } else {
        it->second = e.remote_frames;
      }
    }
    const std::uint64_t dropped = s.info.totals.dropped;
    s.info.totals = st.totals();
    s.info.totals.dropped = dropped;
    s.info.node_map = st.node_map().kind();
    s.info.filter = st.filter_text();
    s.info.ids = st.id_count();
    s.info.max_ids = st.max_ids();
    s.info.nodes = st.node_count();
    s.info.max_nodes = st.max_nodes();
    st.reclaim();  // frees filters replaced since the last cycle, off the I/O thread
  }

  // The steps of `snapshot` (lock held): the id and node statistics, sorted, and the
  // categories of `members` (the node accumulators).
  std::vector<IdStats> id_stats();
  std::vector<NodeStats> node_stats(const std::vector<IdStats>& id_list,
                                    std::vector<NodeAccumulator*>& members);
  std::vector<CategoryStats> categories(const std::vector<NodeAccumulator*>& members,
                                        std::span<const GroupSpec> groups) const;
  // The category of the members in direction `d` that `member(key)` accepts: their counts, and
  // their statistics merged (histograms live, samples in exact mode).
  template <class Member>
  CategoryStats category(const std::vector<NodeAccumulator*>& members, std::string name, bool group,
                         Direction d, Member member) const;
};

CanAggregator::CanAggregator(CanRegistry& registry, CanAggregatorOptions options)
    : impl_(std::make_unique<Impl>(registry, std::move(options))) {}

CanAggregator::~CanAggregator() = default;

void CanAggregator::on_join(const Entry& e) {
  std::lock_guard lock(impl_->mutex);
  if (impl_->slot_of(e.id) != nullptr) return;
  SnifferSlot s;
  s.info.port_id = e.id;
  s.info.name = e.name;
  s.info.port_capacity = e.port ? e.port->capacity() : 0;
  s.state = impl_->registry.find(e.id);  // may still be null: read_tables retries
  const auto it =
      std::lower_bound(impl_->sniffers.begin(), impl_->sniffers.end(), e.id,
                       [](const SnifferSlot& x, std::uint32_t id) { return x.info.port_id < id; });
  impl_->sniffers.insert(it, std::move(s));
}

void CanAggregator::on_leave(const Entry& e) {
  std::lock_guard lock(impl_->mutex);
  SnifferSlot* s = impl_->slot_of(e.id);
  if (s == nullptr) return;
  impl_->read_tables(*s);  // final: the sniffer is gone, its tables no longer change
  s->info.alive = false;
  s->state.reset();
  impl_->registry.release(e.id);
}

void CanAggregator::begin(const Entry& e) {
  impl_->mutex.lock();  // held until end(): one port's batch is applied atomically for readers
  impl_->current = impl_->slot_of(e.id);
  if (SnifferSlot* s = impl_->current; s != nullptr) {
    if (!s->state) s->state = impl_->registry.find(s->info.port_id);
    if (s->state) s->node_map = s->state->node_map().kind();
  }
}

void CanAggregator::on(const Entry& /*e*/, const FrameRecord& r) {
  Impl& m = *impl_;
  // Bus load, controller state, CANopen: decoded here, off the sniffer's real-time path.
  m.protocol.on(r, m.current != nullptr ? m.current->node_map : NodeMapKind::Identity);
  if (r.error) {
    ++m.error_records;  // no node, no timing: counted per error class in the id table
    return;
  }
  ++m.records;
  // Only keys the sniffer tracks are aggregated: memory stays bounded by its tables (and ours).
  IdAccumulator* id = nullptr;
  if (!r.id_untracked) {
    // Peer and flags come with the table entry, read at the end of this batch (before any
    // snapshot can see the key).
    id = m.id_acc(
        IdKey{r.bus, r.id, r.extended, r.rtr, false, r.direction, r.node, r.function, kNoNode, 0});
  }
  if (id != nullptr) {
    id->timing.add(r, r.id_gap_ns);
    id->last_length = r.length;
    id->last_data = r.data;
  } else {
    ++m.unaggregated_id_records;
  }
  NodeAccumulator* node =
      r.node_untracked ? nullptr : m.node_acc(NodeKey{r.bus, r.node, r.direction});
  if (node != nullptr) {
    node->timing.add(r, r.node_gap_ns);
  } else {
    ++m.unaggregated_node_records;
  }
}

void CanAggregator::end(const Entry& /*e*/, const supervisor::PortDrain& d) {
  Impl& m = *impl_;
  if (m.current != nullptr) {
    m.current->info.totals.dropped = d.dropped;
    m.read_tables(*m.current);
    // The tables were read after the cycle began: every frame handled before then is counted.
    m.current->info.observed_ns = d.cycle_ns;
    if (d.emptied) {
      m.current->info.drained_ns = d.cycle_ns;
      m.protocol.advance(d.cycle_ns);  // every record before then was seen: close its seconds
    }
  }
  m.current = nullptr;
  m.mutex.unlock();
}

void CanAggregator::on_cycle(const supervisor::DrainCycle& c) {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->cycles = c.cycle;
  }
  if (!impl_->cycle_hook) return;
  try {
    impl_->cycle_hook(c);
  } catch (...) {
    impl_->hook_failures.fetch_add(1, std::memory_order_relaxed);
  }
}

Nanos CanAggregator::next_deadline() const noexcept {
  return impl_->wake_at.load(std::memory_order_relaxed);
}

void CanAggregator::set_cycle_hook(std::function<void(const supervisor::DrainCycle&)> hook) {
  impl_->cycle_hook = std::move(hook);
}

void CanAggregator::wake_at(Nanos time_ns) noexcept {
  impl_->wake_at.store(time_ns, std::memory_order_relaxed);
}

std::uint64_t CanAggregator::hook_failures() const noexcept {
  return impl_->hook_failures.load(std::memory_order_relaxed);
}

std::uint64_t CanAggregator::cycles() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->cycles;
}

void CanAggregator::visit_gap_distributions(
    std::span<const GroupSpec> groups,
    const std::function<void(const GapDistribution&)>& visit) const {
  Impl& m = *impl_;
  std::lock_guard lock(m.mutex);
  std::vector<NodeAccumulator*> nodes;
  nodes.reserve(m.nodes.size());
  m.nodes.for_each([&](std::uint64_t, NodeAccumulator& a) {
    if (a.timing.records > 0) nodes.push_back(&a);
  });
  std::sort(nodes.begin(), nodes.end(), [](const NodeAccumulator* a, const NodeAccumulator* b) {
    return std::make_tuple(a->key.bus, a->key.node, static_cast<int>(a->key.direction)) <
           std::make_tuple(b->key.bus, b->key.node, static_cast<int>(b->key.direction));
  });
  for (const NodeAccumulator* a : nodes) {
    GapDistribution d;
    d.bus = a->key.bus;
    d.node = a->key.node;
    d.direction = a->key.direction;
    if (a->timing.live) {
      d.stats = &a->timing.gap;
    } else {
      d.samples = a->timing.gaps;
    }
    visit(d);
  }
  const bool exact = m.options.exact_percentiles;
  supervisor::CompactRunningStats merged;  // reused for every group (reset() keeps its buckets)
  std::vector<Nanos> gaps;
  for (const GroupSpec& g : groups) {
    for (const Direction dir : {Direction::Rx, Direction::Tx}) {
      merged.reset();
      gaps.clear();
      bool any = false;
      for (const NodeAccumulator* a : nodes) {
        if (a->key.direction != dir || a->key.node == kNoNode) continue;
        if (!g.contains(a->key.bus, a->key.node)) continue;
        any = true;
        if (exact) {
          gaps.insert(gaps.end(), a->timing.gaps.begin(), a->timing.gaps.end());
        } else {
          merged.merge(a->timing.gap);
        }
      }
      if (!any) continue;
      GapDistribution d;
      d.group = g.name;
      d.direction = dir;
      if (exact) {
        d.samples = gaps;
      } else {
        d.stats = &merged;
      }
      visit(d);
    }
  }
}

namespace {

// The statistics of one id key.
IdStats stats_of(IdAccumulator& a) {
  IdStats s;
  s.bus = a.key.bus;
  s.id = a.key.id;
  s.extended = a.key.extended;
  s.rtr = a.key.rtr;
  s.error = a.key.error;
  s.direction = a.key.direction;
  s.node = a.key.node;
  s.function = a.key.function;
  s.peer = a.key.peer;
  s.flags = a.key.flags;
  const Counted c = sum(a.from);
  s.exact_count = c.any;
  s.frames = c.any ? c.frames : a.timing.records;
  s.first_ns = c.any ? c.first : a.timing.first_record;
  s.last_ns = c.any ? c.last : a.timing.last_record;
  s.records = a.timing.records;
  s.io_ns = a.timing.io_summary();
  s.gap_ns = a.timing.gap_summary(s.gap_exact);
  s.last_length = a.last_length;
  s.last_data = a.last_data;
  return s;
}

// The statistics of one node key, whose frames carried `ids` distinct ids.
NodeStats stats_of(NodeAccumulator& a, std::size_t ids) {
  NodeStats s;
  s.bus = a.key.bus;
  s.node = a.key.node;
  s.direction = a.key.direction;
  const Counted c = sum(a.from);
  s.exact_count = c.any;
  s.frames = c.any ? c.frames : a.timing.records;
  for (const auto& [port, n] : a.remote) s.remote_frames += n;
  s.first_ns = c.any ? c.first : a.timing.first_record;
  s.last_ns = c.any ? c.last : a.timing.last_record;
  s.records = a.timing.records;
  s.ids = ids;
  s.io_ns = a.timing.io_summary();
  s.gap_ns = a.timing.gap_summary(s.gap_exact);
  return s;
}

}  // namespace

std::vector<IdStats> CanAggregator::Impl::id_stats() {
  std::vector<IdStats> out;
  out.reserve(ids.size());
  ids.for_each([&](std::uint64_t, IdAccumulator& a) { out.push_back(stats_of(a)); });
  std::sort(out.begin(), out.end(), [](const IdStats& a, const IdStats& b) {
    return std::make_tuple(a.bus, a.id, a.extended, static_cast<int>(a.direction), a.error, a.rtr) <
           std::make_tuple(b.bus, b.id, b.extended, static_cast<int>(b.direction), b.error, b.rtr);
  });
  return out;
}

std::vector<NodeStats> CanAggregator::Impl::node_stats(const std::vector<IdStats>& id_list,
                                                       std::vector<NodeAccumulator*>& members) {
  // Distinct ids (data frames) per (bus, node, direction).
  std::unordered_map<std::uint64_t, std::size_t> ids_of_node;
  for (const IdStats& s : id_list) {
    if (!s.error && !s.rtr) ++ids_of_node[detail::node_key(s.bus, s.node, is_tx(s.direction))];
  }
  std::vector<NodeStats> out;
  members.reserve(nodes.size());
  out.reserve(nodes.size());
  nodes.for_each([&](std::uint64_t key, NodeAccumulator& a) {
    out.push_back(stats_of(a, ids_of_node[key]));
    members.push_back(&a);
  });
  std::sort(out.begin(), out.end(), [](const NodeStats& a, const NodeStats& b) {
    return std::make_tuple(a.bus, a.node, static_cast<int>(a.direction)) <
           std::make_tuple(b.bus, b.node, static_cast<int>(b.direction));
  });
  return out;
}

template <class Member>
CategoryStats CanAggregator::Impl::category(const std::vector<NodeAccumulator*>& members,
                                            std::string name, bool group, Direction d,
                                            Member member) const {
  const bool exact = options.exact_percentiles;
  const double weight = options.ewma_weight;
  CategoryStats c;
  c.name = std::move(name);
  c.group = group;
  c.direction = d;
  supervisor::CompactRunningStats io;
  supervisor::CompactRunningStats gap;
  supervisor::ScalarStats io_exact;
  supervisor::ScalarStats gap_exact;
  for (auto* r : {&io, &gap}) static_cast<void>(r->set_ewma_weight(weight));
  for (auto* r : {&io_exact, &gap_exact}) static_cast<void>(r->set_ewma_weight(weight));
  std::vector<Nanos> gaps;
  for (const NodeAccumulator* a : members) {
    if (a->key.direction != d || !member(a->key)) continue;
    const Counted counted = sum(a->from);
    const std::uint64_t frames = counted.any ? counted.frames : a->timing.records;
    if (frames == 0) continue;
    if (a->key.node != kNoNode) ++c.nodes;  // the frames of no node count, not as a node
    c.frames += frames;
    for (const auto& [port, n] : a->remote) c.remote_frames += n;
    c.records += a->timing.records;
    c.last_ns = std::max(c.last_ns, counted.any ? counted.last : a->timing.last_record);
    if (exact) {
      io_exact.merge(a->timing.io_exact);
      gap_exact.merge(a->timing.gap_exact);
      gaps.insert(gaps.end(), a->timing.gaps.begin(), a->timing.gaps.end());
    } else {
      io.merge(a->timing.io);
      gap.merge(a->timing.gap);
    }
  }
  if (exact) {
    c.io_ns = io_exact.summary();
    c.gap_ns = gap_exact.summary();
    const StatsSummary e = exact_summary(gaps);
    c.gap_ns.p50 = e.p50;
    c.gap_ns.p90 = e.p90;
    c.gap_ns.p99 = e.p99;
    c.gap_ns.p999 = e.p999;
  } else {
    c.io_ns = io.summary();
    c.gap_ns = gap.summary();
  }
  return c;
}

std::vector<CategoryStats> CanAggregator::Impl::categories(
    const std::vector<NodeAccumulator*>& members, std::span<const GroupSpec> groups) const {
  std::vector<CategoryStats> out;
  for (const Direction d : {Direction::Rx, Direction::Tx}) {
    CategoryStats c = category(members, "all", false, d, [](const NodeKey&) { return true; });
    if (c.frames > 0) out.push_back(std::move(c));
  }
  for (const GroupSpec& g : groups) {
    const auto member = [&](const NodeKey& k) {
      return k.node != kNoNode && g.contains(k.bus, k.node);
    };
    CategoryStats rx = category(members, g.name, true, Direction::Rx, member);
    CategoryStats tx = category(members, g.name, true, Direction::Tx, member);
    const bool none = rx.frames == 0 && tx.frames == 0;
    if (rx.frames > 0 || none) out.push_back(std::move(rx));
    if (tx.frames > 0) out.push_back(std::move(tx));
  }
  return out;
}

CanSnapshot CanAggregator::snapshot(std::span<const GroupSpec> groups) const {
  Impl& m = *impl_;
  std::lock_guard lock(m.mutex);
  CanSnapshot snap;
  snap.cycle = m.cycles;
  snap.records = m.records;
  snap.unaggregated_id_records = m.unaggregated_id_records;
  snap.unaggregated_node_records = m.unaggregated_node_records;
  snap.max_ids = m.ids.max();
  snap.max_nodes = m.nodes.max();
  for (const SnifferSlot& s : m.sniffers) {
    snap.sniffers.push_back(s.info);
    add_totals(snap.totals, s.info.totals);
    if (!s.info.alive) continue;  // gone and read a last time: nothing of it waits anywhere
    // A sniffer not read yet (it joined in a cycle still under way) counts from its first read.
    const auto earliest = [](Nanos a, Nanos b) {
      return a < 0 || b < 0 ? std::max(a, b) : std::min(a, b);
    };
    snap.observed_ns = earliest(snap.observed_ns, s.info.observed_ns);
    snap.drained_ns = earliest(snap.drained_ns, s.info.drained_ns);
  }
  snap.ids = m.id_stats();
  std::vector<NodeAccumulator*> members;
  snap.nodes = m.node_stats(snap.ids, members);
  snap.categories = m.categories(members, groups);
  snap.protocol = m.protocol.snapshot();
  snap.error_records = m.error_records;
  return snap;
}

void CanAggregator::set_protocol_options(ProtocolOptions options) {
  std::lock_guard lock(impl_->mutex);
  impl_->protocol.set_options(std::move(options));
}

std::vector<ProtocolEvent> CanAggregator::protocol_events_after(std::uint64_t after) const {
  std::lock_guard lock(impl_->mutex);
  return impl_->protocol.events_after(after);
}

}  // namespace vigil::can
