#include "vigil/supervisor/health_supervision.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <iterator>
#include <utility>

namespace vigil::supervisor {

HealthSupervision::HealthSupervision(health::HealthConfig config, Clock clock)
    : engine_(std::move(config)), clock_(clock) {}

HealthSupervision::Binding* HealthSupervision::binding(std::uint32_t id) {
  // Ports are drained one after the other: consecutive calls are for the same component.
  if (cached_ != nullptr && cached_id_ == id) return cached_;
  const auto it = bindings_.find(id);
  if (it == bindings_.end()) return nullptr;
  cached_id_ = id;
  cached_ = &it->second;
  return cached_;
}

void HealthSupervision::join(std::uint32_t id, std::string_view name) {
  std::lock_guard lock(mutex_);
  Binding b;
  b.name = std::string(name);
  b.entity = engine_.entity(name);
  b.cycles = engine_.cycles(name);
  cached_ = nullptr;  // the map may rehash
  bindings_[id] = std::move(b);
  if (engine_.entity(name) >= 0) ids_[std::string(name)] = id;
}

void HealthSupervision::leave(std::uint32_t id) {
  std::lock_guard lock(mutex_);
  // Kept (its name for events, its counts): a component that left while running falls silent,
  // which its supervisions see.
  if (Binding* b = binding(id)) b->alive = false;
}

void HealthSupervision::state(std::uint32_t id, const task::StateChange& m) {
  if (m.refused) return;
  std::lock_guard lock(mutex_);
  Binding* b = binding(id);
  if (b == nullptr || b->entity < 0) return;
  if (m.to == TaskState::Running) {
    engine_.activate(b->entity, m.time_ns);
  } else if (m.from == TaskState::Running &&
             (m.to == TaskState::Stopped || m.to == TaskState::PreOperational)) {
    engine_.deactivate(b->entity, m.time_ns);
  }
}

bool HealthSupervision::watches_cycles(std::uint32_t id) {
  std::lock_guard lock(mutex_);
  const Binding* b = binding(id);
  return b != nullptr && b->cycles >= 0;
}

void HealthSupervision::cycle(std::uint32_t id, const task::CycleSample& m) {
  if (m.totals_only) return;
  std::lock_guard lock(mutex_);
  const Binding* b = binding(id);
  if (b == nullptr || b->cycles < 0) return;
  engine_.report(b->cycles, m.end_ns, m.cycle());
}

void HealthSupervision::checkpoint(std::uint32_t id, const health::CheckpointReport& m) {
  std::lock_guard lock(mutex_);
  Binding* b = binding(id);
  if (b == nullptr) return;
  ++b->reports;
  if (m.misuses > b->misuses) b->misuses = m.misuses;
  if (m.index == health::kMisuseIndex) return;
  // Kept for traces, supervised or not.
  if (b->recent.empty()) b->recent.resize(kKeptCheckpoints);
  b->recent[b->next] = Binding::Mark{m.time_ns, m.cycle, m.index};
  b->next = (b->next + 1) % kKeptCheckpoints;
  ++b->kept;
  if (m.index >= b->names.size()) b->names.resize(m.index + std::size_t{1});
  if (b->names[m.index].empty()) b->names[m.index] = std::string(m.name.view());
  if (b->entity < 0) return;
  if (m.index >= b->checkpoints.size()) b->checkpoints.resize(m.index + std::size_t{1}, -2);
  int& handle = b->checkpoints[m.index];
  if (handle == -2) handle = engine_.checkpoint(b->name, m.name.view());
  if (handle >= 0) engine_.report(handle, m.time_ns, m.count);
}

namespace {
EventKind kind_of(health::SupervisionKind k) {
  switch (k) {
    case health::SupervisionKind::Alive:
      return EventKind::AliveSupervision;
    case health::SupervisionKind::Deadline:
      return EventKind::DeadlineSupervision;
    case health::SupervisionKind::Logical:
      return EventKind::LogicalSupervision;
  }
  return EventKind::AliveSupervision;
}
}  // namespace

void HealthSupervision::advance(Nanos now, std::vector<Event>& out) { advance(now, now, out); }

void HealthSupervision::advance(Nanos now, Nanos drained_to, std::vector<Event>& out) {
  std::lock_guard lock(mutex_);
  engine_.advance(now, drained_to);
  for (auto& f : engine_.take_failures()) {
    Event e;
    e.kind = kind_of(f.kind);
    e.severity =
        f.status == health::SupervisionStatus::Expired ? EventSeverity::Error : EventSeverity::Warn;
    if (const auto it = ids_.find(f.entity); it != ids_.end()) e.component_id = it->second;
    e.component = f.entity;
    e.fault_ns = f.fault_ns;
    e.detected_ns = f.detected_ns;
    e.detail = fmt::format("{} '{}' {}: {}: {}", health::to_string(f.kind), f.supervision,
                           health::to_string(f.status), health::to_string(f.failure), f.text);
    out.push_back(std::move(e));
  }
  for (auto& [id, b] : bindings_) {
    if (b.misuses == b.misuses_raised) continue;
    Event e;
    e.kind = EventKind::CheckpointMisuse;
    e.severity = EventSeverity::Warn;
    e.component_id = id;
    e.component = b.name;
    e.detected_ns = now;
    e.count = b.misuses - b.misuses_raised;
    e.detail =
        fmt::format("{} report{} of a checkpoint id the component did not declare ({} in all)",
                    e.count, e.count == 1 ? "" : "s", b.misuses);
    b.misuses_raised = b.misuses;
    out.push_back(std::move(e));
  }
}

Nanos HealthSupervision::next_deadline() const {
  std::lock_guard lock(mutex_);
  return engine_.next_deadline();
}

std::vector<health::SupervisionReport> HealthSupervision::reports() const {
  std::lock_guard lock(mutex_);
  return engine_.reports();
}

health::SupervisionStatus HealthSupervision::status(std::string_view name) const {
  std::lock_guard lock(mutex_);
  return engine_.status(name);
}

bool HealthSupervision::deactivate(std::string_view entity) {
  std::lock_guard lock(mutex_);
  const int e = engine_.entity(entity);
  if (e < 0) return false;
  engine_.deactivate(e, clock_.now());
  return true;
}

bool HealthSupervision::activate(std::string_view entity) {
  std::lock_guard lock(mutex_);
  const int e = engine_.entity(entity);
  if (e < 0) return false;
  engine_.activate(e, clock_.now());
  return true;
}

void HealthSupervision::trace(std::uint32_t id, Nanos from,
                              std::vector<health::CheckpointMark>& marks,
                              std::vector<health::DeadlineSpan>& spans) const {
  std::lock_guard lock(mutex_);
  const auto it = bindings_.find(id);
  if (it == bindings_.end()) return;
  const Binding& b = it->second;
  const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(b.kept, kKeptCheckpoints));
  for (std::size_t i = 0; i < n; ++i) {
    const Binding::Mark& m = b.recent[(b.next + kKeptCheckpoints - n + i) % kKeptCheckpoints];
    if (m.time < from) continue;
    marks.push_back(health::CheckpointMark{b.names[m.index], m.time, m.cycle});
  }
  auto s = engine_.deadline_spans(b.name, from);
  spans.insert(spans.end(), std::make_move_iterator(s.begin()), std::make_move_iterator(s.end()));
}

std::vector<CheckpointUse> HealthSupervision::checkpoint_use() const {
  std::lock_guard lock(mutex_);
  std::vector<CheckpointUse> out;
  for (const auto& [id, b] : bindings_) {
    if (b.reports > 0 || b.misuses > 0) out.push_back(CheckpointUse{b.name, b.reports, b.misuses});
  }
  return out;
}

}  // namespace vigil::supervisor
