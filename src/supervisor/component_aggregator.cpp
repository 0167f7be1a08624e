#include "vigil/supervisor/component_aggregator.hpp"

#include <cxxabi.h>

#include <algorithm>
#include <cstdlib>

#include "vigil/task/shm_messages.hpp"

namespace vigil {

namespace {
// Total time is user time plus the latest measured supervision overhead: its count, extremes,
// mean and EWMA are kept exactly here (ScalarStats), and its percentiles are user time's plus that
// overhead, so the aggregator keeps no fifth histogram per component (9 KiB and one more bucket
// update per message).
struct TotalStats {
  ScalarStats stats;  // count, last, min, max, mean, EWMA: the same code as RunningStats'

  void add(Nanos v) noexcept { stats.add(v); }
  [[nodiscard]] StatsSummary summary(const StatsSummary& user, Nanos overhead) const noexcept {
    StatsSummary s = stats.summary();
    if (s.count == 0) return s;
    auto shifted = [&](Nanos p) { return std::min(p + overhead, s.max); };
    s.p50 = shifted(user.p50);
    s.p90 = shifted(user.p90);
    s.p99 = shifted(user.p99);
    s.p999 = shifted(user.p999);
    return s;
  }
};
}  // namespace

struct ComponentAggregator::Slot {
  mutable std::mutex mutex;
  ComponentSnapshot data;  // summaries are filled only in copies handed to readers
  RunningStats user, latency, period, overhead;
  TotalStats total;
  Nanos last_overhead = 0;
};

namespace {

std::string demangle(const char* mangled) {
  int status = 0;
  char* s = abi::__cxa_demangle(mangled, nullptr, nullptr, &status);
  if (status != 0 || s == nullptr) return mangled;
  std::string out(s);
  std::free(s);
  return out;
}

}  // namespace

ComponentAggregator::ComponentAggregator(AggregatorOptions options)
    : options_(options), ewma_weight_(options.ewma_weight) {}
ComponentAggregator::~ComponentAggregator() = default;

ComponentAggregator::Slot* ComponentAggregator::slot_for(const Entry& e) {
  // Called by the supervisor thread, the only writer of slots_: no lock needed to read it.
  // The supervisor visits ports in id order, so the slot after the previous one is the usual
  // answer; otherwise a binary search over the contiguous ids (no pointer chasing: with
  // thousands of components every dereference would be a cache miss).
  if (hint_ < ids_.size() && ids_[hint_] == e.id) return slots_[hint_++].get();
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), e.id);
  if (it == ids_.end() || *it != e.id) return nullptr;
  const auto i = static_cast<std::size_t>(it - ids_.begin());
  hint_ = i + 1;
  return slots_[i].get();
}

void ComponentAggregator::on_join(const Entry& e) {
  auto slot = std::make_unique<Slot>();
  slot->data.id = e.id;
  slot->data.name = e.name;
  slot->data.joined_at = options_.clock.now();
  slot->data.port_capacity = e.port->capacity();
  for (RunningStats* s : {&slot->user, &slot->latency, &slot->period, &slot->overhead}) {
    (void)s->set_ewma_weight(ewma_weight_.load(std::memory_order_relaxed));
  }
  (void)slot->total.stats.set_ewma_weight(ewma_weight_.load(std::memory_order_relaxed));
  std::unique_lock lock(list_mutex_);
  const auto at = std::lower_bound(ids_.begin(), ids_.end(), e.id) - ids_.begin();
  ids_.insert(ids_.begin() + at, e.id);
  slots_.insert(slots_.begin() + at, std::move(slot));
  hint_ = 0;
}

void ComponentAggregator::on_leave(const Entry& e) {
  if (Slot* s = slot_for(e)) {
    std::lock_guard lock(s->mutex);
    s->data.alive = false;
    s->data.left_at = options_.clock.now();
    ++departed_;
  }
}

void ComponentAggregator::begin(const Entry& e) {
  current_ = slot_for(e);
  if (current_ != nullptr) current_->mutex.lock();
  // One clock read per port drain, not per message: every sample of a batch arrived now.
  drain_time_ = options_.clock.now();
}

void ComponentAggregator::end(const Entry& /*e*/, const PortDrain& d) {
  if (current_ == nullptr) return;
  auto& data = current_->data;
  data.port_high_water = std::max(data.port_high_water, d.occupancy);
  data.counters.dropped = std::max(data.counters.dropped, d.dropped);
  current_->mutex.unlock();
  current_ = nullptr;
}

void ComponentAggregator::on(const Entry& /*e*/, const TaskInfo& m) {
  if (current_ == nullptr) return;
  current_->data.has_info = true;
  current_->data.info = m;
}

void ComponentAggregator::on(const Entry& /*e*/, const CycleSample& m) {
  if (current_ == nullptr) return;
  Slot& s = *current_;
  auto& d = s.data;
  // Counters only grow: merging keeps the larger of each, so a late totals-only sample or an
  // exception report counted before its sample never moves one back.
  d.counters.merge(m.counters);
  d.state = m.state;
  if (m.totals_only) return;
  if (d.has_sample && m.cycle() == d.last.cycle() + 1) {
    s.period.add(m.start_ns - d.last.start_ns);
  }
  if (m.overhead_ns > 0) {
    s.last_overhead = m.overhead_ns;
    s.overhead.add(m.overhead_ns);
  }
  const Nanos user = m.end_ns - m.start_ns;
  s.user.add(user);
  s.total.add(user + s.last_overhead);
  s.latency.add(m.start_ns - m.release_ns);
  d.has_sample = true;
  d.last = m;
  ++d.samples;
  d.last_sample_at = drain_time_;
}

void ComponentAggregator::on(const Entry& /*e*/, const RealTimeLoss& m) {
  // The cumulative counters of the samples are authoritative for counts (a loss report can be
  // dropped by a full port); the report tells which cycle lost, and when it arrived.
  if (current_ == nullptr) return;
  current_->data.has_loss = true;
  current_->data.last_loss = m;
  current_->data.last_loss_at = drain_time_;
}

void ComponentAggregator::on(const Entry& /*e*/, const ExceptionReport& m) {
  if (current_ == nullptr) return;
  Slot& s = *current_;
  s.data.has_exception = true;
  s.data.last_exception = m;
  s.data.last_exception_type = demangle(m.type.c_str());
  s.data.counters.exceptions = std::max(s.data.counters.exceptions, std::uint64_t{m.count});
}

void ComponentAggregator::on(const Entry& /*e*/, const StateChange& m) {
  if (current_ == nullptr) return;
  current_->data.has_state_change = true;
  current_->data.last_change = m;
  current_->data.state = m.to;
}

void ComponentAggregator::on(const Entry& e, const log::LogRecord& m) {
  if (auto* c = log_consumer_.load()) c->on_record(e.id, e.name, m);
}

void ComponentAggregator::on_cycle(const SupervisorCycle& c) {
  if (auto* lc = log_consumer_.load()) lc->on_supervisor_cycle(c.time_ns + c.drain_ns);
  hint_ = 0;
  if (departed_ == 0) return;  // nothing to forget: no walk over thousands of records
  const Nanos now = options_.clock.now();
  const auto expired = [&](const auto& s) {
    return !s->data.alive && now - s->data.left_at > options_.retain_left_ns;
  };
  if (std::none_of(slots_.begin(), slots_.end(), expired)) return;
  std::unique_lock lock(list_mutex_);
  std::size_t out = 0;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (expired(slots_[i])) {
      --departed_;
      continue;
    }
    slots_[out] = std::move(slots_[i]);
    ids_[out] = ids_[i];
    ++out;
  }
  slots_.resize(out);
  ids_.resize(out);
}

namespace {
ComponentSnapshot copy_of(const ComponentAggregator::Slot& s) {
  std::lock_guard lock(s.mutex);
  ComponentSnapshot out = s.data;
  out.user_ns = s.user.summary();
  out.total_ns = s.total.summary(out.user_ns, s.last_overhead);
  out.latency_ns = s.latency.summary();
  out.period_ns = s.period.summary();
  out.overhead_ns = s.overhead.summary();
  return out;
}
}  // namespace

std::vector<ComponentSnapshot> ComponentAggregator::snapshot() const {
  std::shared_lock lock(list_mutex_);
  std::vector<ComponentSnapshot> out;
  out.reserve(slots_.size());
  for (const auto& s : slots_) out.push_back(copy_of(*s));
  return out;
}

std::optional<ComponentSnapshot> ComponentAggregator::find(std::string_view name) const {
  std::shared_lock lock(list_mutex_);
  const Slot* dead = nullptr;
  for (const auto& s : slots_) {
    if (s->data.name != name) continue;
    if (s->data.alive) return copy_of(*s);
    dead = s.get();
  }
  if (dead != nullptr) return copy_of(*dead);
  return std::nullopt;
}

void ComponentAggregator::visit_distributions(
    const std::function<void(const ComponentDistributions&)>& visit) const {
  std::shared_lock lock(list_mutex_);
  for (const auto& s : slots_) {
    std::lock_guard slot_lock(s->mutex);
    ComponentDistributions d;
    d.id = s->data.id;
    d.name = s->data.name;
    d.user = &s->user;
    d.latency = &s->latency;
    d.period = &s->period;
    d.overhead = &s->overhead;
    d.total_shift_ns = s->last_overhead;
    d.total = s->total.summary(StatsSummary{}, 0);
    visit(d);
  }
}

std::size_t ComponentAggregator::size() const {
  std::shared_lock lock(list_mutex_);
  return slots_.size();
}

void ComponentAggregator::set_ewma_weight(double w) {
  std::shared_lock lock(list_mutex_);
  for (const auto& s : slots_) {
    std::lock_guard slot_lock(s->mutex);
    for (RunningStats* r : {&s->user, &s->latency, &s->period, &s->overhead}) {
      (void)r->set_ewma_weight(w);
    }
    (void)s->total.stats.set_ewma_weight(w);
  }
  ewma_weight_.store(w, std::memory_order_relaxed);
}

}  // namespace vigil
