#include "vigil/can/can_statistics.hpp"

#include <algorithm>
#include <mutex>
#include <tuple>
#include <unordered_map>

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

const IdStats* CanSnapshot::find_id(std::uint8_t bus, std::uint32_t id, bool extended,
                                    Direction d) const noexcept {
  const auto key = [](const IdStats& s) {
    return std::make_tuple(s.bus, s.id, s.extended, static_cast<int>(s.direction));
  };
  const auto want = std::make_tuple(bus, id, extended, static_cast<int>(d));
  const auto it = std::lower_bound(ids.begin(), ids.end(), want,
                                   [&](const IdStats& s, const auto& w) { return key(s) < w; });
  return it != ids.end() && key(*it) == want ? &*it : nullptr;
}

StatsSummary exact_summary(std::vector<Nanos>& samples) {
  StatsSummary s;
  if (samples.empty()) return s;
  std::sort(samples.begin(), samples.end());
  const auto n = static_cast<std::uint64_t>(samples.size());
  s.count = n;
  s.min = samples.front();
  s.max = samples.back();
  long double sum = 0;
  for (const Nanos v : samples) sum += static_cast<long double>(v);
  s.mean = static_cast<double>(sum / static_cast<long double>(n));
  const auto at = [&](double q) { return samples[vigil::detail::nearest_rank(q, n) - 1]; };
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

// Timing of one key, fed by records.
struct Timing {
  std::uint64_t records = 0;
  Nanos first_record = 0;
  Nanos last_record = 0;
  RunningStats io;
  RunningStats gap;
  std::vector<Nanos> exact_gaps;  // exact_percentiles only

  void add(const FrameRecord& r, Nanos gap_ns, bool exact) {
    if (records == 0) first_record = r.end_ns;
    ++records;
    last_record = std::max(last_record, r.end_ns);
    io.add(r.io_ns());
    if (gap_ns >= 0) {
      gap.add(gap_ns);
      if (exact) exact_gaps.push_back(gap_ns);
    }
  }

  StatsSummary gap_summary(bool exact, bool& is_exact) {
    StatsSummary s = gap.summary();
    is_exact = false;
    if (exact && !exact_gaps.empty()) {
      const StatsSummary e = exact_summary(exact_gaps);
      s.p50 = e.p50;
      s.p90 = e.p90;
      s.p99 = e.p99;
      s.p999 = e.p999;
      is_exact = true;
    }
    return s;
  }
};

struct IdAccumulator {
  std::uint8_t bus = 0;
  std::uint32_t id = 0;
  bool extended = false;
  Direction direction = Direction::Rx;
  std::uint32_t node = 0;
  std::uint32_t function = 0;
  std::vector<Contribution> from;
  Timing timing;
  std::uint8_t last_length = 0;
  std::array<std::uint8_t, 8> last_data{};
};

struct NodeAccumulator {
  std::uint8_t bus = 0;
  std::uint32_t node = 0;
  Direction direction = Direction::Rx;
  std::vector<Contribution> from;
  Timing timing;
};

struct SnifferSlot {
  SnifferInfo info;
  std::shared_ptr<detail::SnifferState> state;
};

bool is_tx(Direction d) { return d == Direction::Tx; }

void add_totals(SnifferTotals& a, const SnifferTotals& b) {
  a.frames += b.frames;
  a.rx += b.rx;
  a.tx += b.tx;
  a.error_frames += b.error_frames;
  a.rejected += b.rejected;
  a.accepted += b.accepted;
  a.untracked_ids += b.untracked_ids;
  a.untracked_nodes += b.untracked_nodes;
  a.dropped += b.dropped;
  a.filter_changes += b.filter_changes;
}

}  // namespace

struct CanAggregator::Impl {
  CanRegistry& registry;
  CanAggregatorOptions options;

  mutable std::mutex mutex;           // guards everything below
  std::vector<SnifferSlot> sniffers;  // by port id
  std::unordered_map<std::uint64_t, std::unique_ptr<IdAccumulator>> ids;
  std::unordered_map<std::uint64_t, std::unique_ptr<NodeAccumulator>> nodes;
  std::uint64_t records = 0;
  std::uint64_t cycles = 0;

  // Supervisor thread only.
  SnifferSlot* current = nullptr;
  std::uint64_t cached_id_key = 0;
  IdAccumulator* cached_id = nullptr;
  std::uint64_t cached_node_key = 0;
  NodeAccumulator* cached_node = nullptr;
  std::vector<IdEntry> id_scratch;
  std::vector<NodeEntry> node_scratch;

  Impl(CanRegistry& r, CanAggregatorOptions o) : registry(r), options(o) {}

  SnifferSlot* slot_of(std::uint32_t port) {
    for (SnifferSlot& s : sniffers) {
      if (s.info.port_id == port) return &s;
    }
    return nullptr;
  }

  RunningStats fresh() const {
    RunningStats s;
    static_cast<void>(s.set_ewma_weight(options.ewma_weight));
    return s;
  }

  IdAccumulator& id_slot(std::uint64_t key, std::uint8_t bus, std::uint32_t id, bool extended,
                         Direction d, std::uint32_t node, std::uint32_t function) {
    if (key == cached_id_key && cached_id != nullptr) return *cached_id;
    auto& p = ids[key];
    if (!p) {
      p = std::make_unique<IdAccumulator>();
      p->bus = bus;
      p->id = id;
      p->extended = extended;
      p->direction = d;
      p->node = node;
      p->function = function;
      p->timing.io = fresh();
      p->timing.gap = fresh();
    }
    cached_id_key = key;
    cached_id = p.get();
    return *p;
  }

  NodeAccumulator& node_slot(std::uint64_t key, std::uint8_t bus, std::uint32_t node, Direction d) {
    if (key == cached_node_key && cached_node != nullptr) return *cached_node;
    auto& p = nodes[key];
    if (!p) {
      p = std::make_unique<NodeAccumulator>();
      p->bus = bus;
      p->node = node;
      p->direction = d;
      p->timing.io = fresh();
      p->timing.gap = fresh();
    }
    cached_node_key = key;
    cached_node = p.get();
    return *p;
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
      IdAccumulator& slot = id_slot(detail::id_key(e.bus, e.id, e.extended, is_tx(e.direction)),
                                    e.bus, e.id, e.extended, e.direction, e.node, e.function);
      contribute(slot.from, port, e.frames, e.first_ns, e.last_ns);
    }
    node_scratch.clear();
    st.read_nodes(node_scratch);
    for (const NodeEntry& e : node_scratch) {
      NodeAccumulator& slot = node_slot(detail::node_key(e.bus, e.node, is_tx(e.direction)), e.bus,
                                        e.node, e.direction);
      contribute(slot.from, port, e.frames, e.first_ns, e.last_ns);
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
};

CanAggregator::CanAggregator(CanRegistry& registry, CanAggregatorOptions options)
    : impl_(std::make_unique<Impl>(registry, options)) {}

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
}

void CanAggregator::on(const Entry& /*e*/, const FrameRecord& r) {
  Impl& m = *impl_;
  const bool exact = m.options.exact_percentiles;
  IdAccumulator& id = m.id_slot(detail::id_key(r.bus, r.id, r.extended, is_tx(r.direction)), r.bus,
                                r.id, r.extended, r.direction, r.node, r.function);
  id.timing.add(r, r.id_gap_ns, exact);
  id.last_length = r.length;
  id.last_data = r.data;
  NodeAccumulator& node =
      m.node_slot(detail::node_key(r.bus, r.node, is_tx(r.direction)), r.bus, r.node, r.direction);
  node.timing.add(r, r.node_gap_ns, exact);
  ++m.records;
}

void CanAggregator::end(const Entry& /*e*/, const PortDrain& d) {
  Impl& m = *impl_;
  if (m.current != nullptr) {
    m.current->info.totals.dropped = d.dropped;
    m.read_tables(*m.current);
  }
  m.current = nullptr;
  m.mutex.unlock();
}

void CanAggregator::on_cycle(const SupervisorCycle& c) {
  std::lock_guard lock(impl_->mutex);
  impl_->cycles = c.cycle;
}

std::uint64_t CanAggregator::cycles() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->cycles;
}

CanSnapshot CanAggregator::snapshot(std::span<const GroupSpec> groups) const {
  Impl& m = *impl_;
  std::lock_guard lock(m.mutex);
  const bool exact = m.options.exact_percentiles;
  CanSnapshot snap;
  snap.cycle = m.cycles;
  snap.records = m.records;
  for (const SnifferSlot& s : m.sniffers) {
    snap.sniffers.push_back(s.info);
    add_totals(snap.totals, s.info.totals);
  }

  snap.ids.reserve(m.ids.size());
  for (auto& [key, p] : m.ids) {
    IdAccumulator& slot = *p;
    IdStats s;
    s.bus = slot.bus;
    s.id = slot.id;
    s.extended = slot.extended;
    s.direction = slot.direction;
    s.node = slot.node;
    s.function = slot.function;
    const Counted c = sum(slot.from);
    s.exact_count = c.any;
    s.frames = c.any ? c.frames : slot.timing.records;
    s.first_ns = c.any ? c.first : slot.timing.first_record;
    s.last_ns = c.any ? c.last : slot.timing.last_record;
    s.records = slot.timing.records;
    s.io_ns = slot.timing.io.summary();
    s.gap_ns = slot.timing.gap_summary(exact, s.gap_exact);
    s.last_length = slot.last_length;
    s.last_data = slot.last_data;
    snap.ids.push_back(s);
  }
  std::sort(snap.ids.begin(), snap.ids.end(), [](const IdStats& a, const IdStats& b) {
    return std::make_tuple(a.bus, a.id, a.extended, static_cast<int>(a.direction)) <
           std::make_tuple(b.bus, b.id, b.extended, static_cast<int>(b.direction));
  });

  // Distinct ids per (bus, node, direction).
  std::unordered_map<std::uint64_t, std::size_t> ids_of_node;
  for (const IdStats& s : snap.ids)
    ++ids_of_node[detail::node_key(s.bus, s.node, is_tx(s.direction))];

  std::vector<const NodeAccumulator*> node_slots;
  node_slots.reserve(m.nodes.size());
  snap.nodes.reserve(m.nodes.size());
  for (auto& [key, p] : m.nodes) {
    NodeAccumulator& slot = *p;
    NodeStats s;
    s.bus = slot.bus;
    s.node = slot.node;
    s.direction = slot.direction;
    const Counted c = sum(slot.from);
    s.exact_count = c.any;
    s.frames = c.any ? c.frames : slot.timing.records;
    s.first_ns = c.any ? c.first : slot.timing.first_record;
    s.last_ns = c.any ? c.last : slot.timing.last_record;
    s.records = slot.timing.records;
    s.ids = ids_of_node[key];
    s.io_ns = slot.timing.io.summary();
    s.gap_ns = slot.timing.gap_summary(exact, s.gap_exact);
    snap.nodes.push_back(s);
    node_slots.push_back(&slot);
  }
  std::sort(snap.nodes.begin(), snap.nodes.end(), [](const NodeStats& a, const NodeStats& b) {
    return std::make_tuple(a.bus, a.node, static_cast<int>(a.direction)) <
           std::make_tuple(b.bus, b.node, static_cast<int>(b.direction));
  });

  // Categories: merge the members' statistics.
  const auto category = [&](std::string name, bool group, Direction d, auto&& member) {
    CategoryStats c;
    c.name = std::move(name);
    c.group = group;
    c.direction = d;
    RunningStats io = m.fresh();
    RunningStats gap = m.fresh();
    for (const NodeAccumulator* slot : node_slots) {
      if (slot->direction != d || !member(*slot)) continue;
      const Counted counted = sum(slot->from);
      const std::uint64_t frames = counted.any ? counted.frames : slot->timing.records;
      if (frames == 0) continue;
      ++c.nodes;
      c.frames += frames;
      c.records += slot->timing.records;
      c.last_ns = std::max(c.last_ns, counted.any ? counted.last : slot->timing.last_record);
      io.merge(slot->timing.io);
      gap.merge(slot->timing.gap);
    }
    c.io_ns = io.summary();
    c.gap_ns = gap.summary();
    return c;
  };
  for (const Direction d : {Direction::Rx, Direction::Tx}) {
    CategoryStats c = category("all", false, d, [](const NodeAccumulator&) { return true; });
    if (c.frames > 0) snap.categories.push_back(std::move(c));
  }
  for (const GroupSpec& g : groups) {
    const auto member = [&](const NodeAccumulator& s) { return g.contains(s.bus, s.node); };
    CategoryStats rx = category(g.name, true, Direction::Rx, member);
    CategoryStats tx = category(g.name, true, Direction::Tx, member);
    const bool none = rx.frames == 0 && tx.frames == 0;
    if (rx.frames > 0 || none) snap.categories.push_back(std::move(rx));
    if (tx.frames > 0) snap.categories.push_back(std::move(tx));
  }
  return snap;
}

}  // namespace vigil::can
