#include "vigil/supervisor/events.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <system_error>
#include <thread>

#include "vigil/platform/thread.hpp"

namespace vigil::supervisor {

const char* to_string(EventKind k) noexcept {
  switch (k) {
    case EventKind::Exception:
      return "exception";
    case EventKind::OverrunLimit:
      return "overrun_limit";
    case EventKind::FaultState:
      return "fault_state";
    case EventKind::StateChange:
      return "state_change";
    case EventKind::Overrun:
      return "overrun";
    case EventKind::RealTimeLoss:
      return "rt_loss";
    case EventKind::Deadline:
      return "deadline";
    case EventKind::Recovered:
      return "recovered";
    case EventKind::Cleared:
      return "cleared";
    case EventKind::Joined:
      return "joined";
    case EventKind::Left:
      return "left";
    case EventKind::ProcessExited:
      return "process_exited";
    case EventKind::SegmentRejected:
      return "segment_rejected";
    case EventKind::ProcessStopped:
      return "process_stopped";
    case EventKind::ProcessContinued:
      return "process_continued";
    case EventKind::NotResponding:
      return "not_responding";
    case EventKind::Responding:
      return "responding";
    case EventKind::AliveSupervision:
      return "alive_supervision";
    case EventKind::DeadlineSupervision:
      return "deadline_supervision";
    case EventKind::LogicalSupervision:
      return "logical_supervision";
    case EventKind::CheckpointMisuse:
      return "checkpoint_misuse";
    case EventKind::NmtState:
      return "nmt_state";
    case EventKind::NodeReset:
      return "node_reset";
    case EventKind::Emergency:
      return "emergency";
    case EventKind::NmtCommand:
      return "nmt_command";
    case EventKind::ErrorWarning:
      return "error_warning";
    case EventKind::ErrorPassive:
      return "error_passive";
    case EventKind::BusOff:
      return "bus_off";
    case EventKind::ErrorActive:
      return "error_active";
    case EventKind::NodeHealth:
      return "node_health";
    case EventKind::DtcActive:
      return "dtc_active";
    case EventKind::DtcCleared:
      return "dtc_cleared";
    case EventKind::AddressClaim:
      return "address_claim";
    case EventKind::SegmentCorrupted:
      return "segment_corrupted";
    case EventKind::SupervisorRestarted:
      return "supervisor_restarted";
    case EventKind::Reaction:
      return "reaction";
    case EventKind::ThreadStalled:
      return "thread_stalled";
    case EventKind::ThreadResumed:
      return "thread_resumed";
  }
  return "?";
}

std::optional<EventKind> parse_event_kind(std::string_view name) noexcept {
  for (auto k = static_cast<std::uint8_t>(EventKind::Exception);
       k <= static_cast<std::uint8_t>(EventKind::ThreadResumed); ++k) {
    if (name == to_string(static_cast<EventKind>(k))) return static_cast<EventKind>(k);
  }
  return std::nullopt;
}

std::vector<std::string_view> event_kind_names() {
  std::vector<std::string_view> out;
  for (auto k = static_cast<std::uint8_t>(EventKind::Exception);
       k <= static_cast<std::uint8_t>(EventKind::ThreadResumed); ++k) {
    out.emplace_back(to_string(static_cast<EventKind>(k)));
  }
  return out;
}

const char* to_string(EventSeverity s) noexcept {
  switch (s) {
    case EventSeverity::Info:
      return "info";
    case EventSeverity::Warn:
      return "warn";
    case EventSeverity::Error:
      return "error";
  }
  return "?";
}

std::string format_event(const Event& e) {
  std::string s = fmt::format("{} {}: {}",
                              e.severity == EventSeverity::Error  ? "ERROR"
                              : e.severity == EventSeverity::Warn ? "WARN"
                                                                  : "INFO",
                              e.component, to_string(e.kind));
  if (!e.detail.empty()) s += ": " + e.detail;
  if (e.count > 1) s += fmt::format(" (x{})", e.count);
  if (e.cycle > 0)
    s += fmt::format(" [cycle {}", e.cycle);
  else
    s += " [";
  if (e.fault_ns > 0) {
    s += fmt::format("{}detected {:.1f} ms after the fault", e.cycle > 0 ? ", " : "",
                     static_cast<double>(e.latency_ns()) / 1e6);
  }
  s += ']';
  if (s.ends_with(" []")) s.resize(s.size() - 3);
  return s;
}

// --- EventHub ---

struct EventHub::Subscriber {
  std::uint64_t id = 0;
  EventCallback callback;
  std::mutex mutex;
  std::condition_variable cv;       // events queued, or quit
  std::condition_variable idle_cv;  // queue empty and no callback under way
  std::vector<Event> ring;          // fixed capacity, allocated at subscribe
  std::size_t head = 0;             // next to deliver
  std::size_t size = 0;
  bool busy = false;
  bool quit = false;
  std::uint64_t delivered = 0;
  std::uint64_t lost = 0;
  platform::Thread thread;

  // Supervisor side: a copy under the lock, or a count when full.
  void push(const Event& e) {
    {
      std::lock_guard lock(mutex);
      if (size == ring.size()) {
        ++lost;
        return;
      }
      ring[(head + size) % ring.size()] = e;
      ++size;
    }
    cv.notify_one();
  }

  void run() {
    Event e;
    std::unique_lock lock(mutex);
    for (;;) {
      cv.wait(lock, [&] { return quit || size > 0; });
      if (quit) return;
      e = std::move(ring[head]);
      head = (head + 1) % ring.size();
      --size;
      busy = true;
      lock.unlock();
      try {
        callback(e);
      } catch (...) {
      }
      lock.lock();
      busy = false;
      ++delivered;
      if (size == 0) idle_cv.notify_all();
    }
  }
};

EventHub::EventHub(EventHubOptions options) : options_(options) {
  options_.queue_capacity = std::max<std::size_t>(options_.queue_capacity, 1);
}

EventHub::~EventHub() {
  std::vector<std::shared_ptr<Subscriber>> subs;
  {
    std::lock_guard lock(mutex_);
    subs.swap(subscribers_);
  }
  for (auto& s : subs) {
    {
      std::lock_guard lock(s->mutex);
      s->quit = true;
    }
    s->cv.notify_all();
    s->thread.join();
  }
}

std::uint64_t EventHub::subscribe(EventCallback callback, std::size_t capacity) {
  return subscribe(std::move(callback), capacity, platform::SchedPolicy::Other, 0);
}

std::uint64_t EventHub::subscribe(EventCallback callback, std::size_t capacity,
                                  platform::SchedPolicy policy, int priority) {
  auto s = std::make_shared<Subscriber>();
  s->callback = std::move(callback);
  s->ring.resize(capacity != 0 ? capacity : options_.queue_capacity);
  {
    std::lock_guard lock(mutex_);
    s->id = next_id_++;
  }
  platform::ThreadConfig tc;
  tc.name = "vigil-events";
  tc.policy = policy;
  tc.priority = policy == platform::SchedPolicy::Fifo ? priority : 0;
  auto t = platform::Thread::spawn(tc, [raw = s.get()] { raw->run(); });
  if (!t && policy == platform::SchedPolicy::Fifo) {  // refused: SCHED_OTHER
    tc.policy = platform::SchedPolicy::Other;
    tc.priority = 0;
    t = platform::Thread::spawn(tc, [raw = s.get()] { raw->run(); });
  }
  if (!t) throw std::system_error(t.error().code, std::generic_category(), t.error().message);
  s->thread = std::move(*t);
  std::lock_guard lock(mutex_);
  subscribers_.push_back(s);
  return s->id;
}

void EventHub::unsubscribe(std::uint64_t id) {
  std::shared_ptr<Subscriber> s;
  {
    std::lock_guard lock(mutex_);
    const auto it = std::find_if(subscribers_.begin(), subscribers_.end(),
                                 [&](const auto& p) { return p->id == id; });
    if (it == subscribers_.end()) return;
    s = *it;
    subscribers_.erase(it);
  }
  {
    std::lock_guard lock(s->mutex);
    s->quit = true;
  }
  s->cv.notify_all();
  s->thread.join();
  // No publish() reaches it any more (it left the list under mutex_).
  std::lock_guard hub_lock(mutex_);
  lost_gone_ += s->lost;
}

bool EventHub::flush(Nanos timeout_ns) {
  std::vector<std::shared_ptr<Subscriber>> subs;
  {
    std::lock_guard lock(mutex_);
    subs = subscribers_;
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  bool all = true;
  for (auto& s : subs) {
    std::unique_lock lock(s->mutex);
    all = s->idle_cv.wait_until(lock, deadline, [&] { return s->size == 0 && !s->busy; }) && all;
  }
  return all;
}

SubscriberStats EventHub::stats(std::uint64_t id) const {
  std::shared_ptr<Subscriber> s;
  {
    std::lock_guard lock(mutex_);
    for (const auto& p : subscribers_) {
      if (p->id == id) s = p;
    }
  }
  if (!s) return {};
  std::lock_guard lock(s->mutex);
  return {s->delivered, s->lost, s->ring.size()};
}

std::uint64_t EventHub::publish(Event e) {
  std::vector<std::shared_ptr<Subscriber>>* subs = nullptr;
  std::uint64_t seq = 0;
  std::unique_lock lock(mutex_);
  seq = e.seq = ++seq_;
  recent_.push_back(e);
  while (recent_.size() > std::max<std::size_t>(options_.recent, 1)) recent_.pop_front();
  subs = &subscribers_;
  // Subscribers are only added or removed under mutex_, and push() takes only the subscriber's
  // own lock for one copy: holding the hub's lock meanwhile keeps the order of events the same
  // for every subscriber.
  for (auto& s : *subs) s->push(e);
  lock.unlock();
  published_cv_.notify_all();
  return seq;
}

std::vector<Event> EventHub::since(std::uint64_t after, std::size_t max) const {
  std::lock_guard lock(mutex_);
  std::vector<Event> out;
  for (const Event& e : recent_) {
    if (e.seq <= after) continue;
    if (out.size() >= max) break;
    out.push_back(e);
  }
  return out;
}

bool EventHub::wait(std::uint64_t after, Nanos timeout_ns) const {
  std::unique_lock lock(mutex_);
  const std::uint64_t gen = cancel_gen_;
  published_cv_.wait_for(lock, std::chrono::nanoseconds(timeout_ns),
                         [&] { return seq_ > after || cancel_gen_ != gen; });
  return seq_ > after;
}

void EventHub::cancel_waits() {
  {
    std::lock_guard lock(mutex_);
    ++cancel_gen_;
  }
  published_cv_.notify_all();
}

std::uint64_t EventHub::last_seq() const {
  std::lock_guard lock(mutex_);
  return seq_;
}

std::uint64_t EventHub::lost() const {
  std::vector<std::shared_ptr<Subscriber>> subs;
  std::uint64_t n = 0;
  {
    std::lock_guard lock(mutex_);
    subs = subscribers_;
    n = lost_gone_;
  }
  for (auto& s : subs) {
    std::lock_guard lock(s->mutex);
    n += s->lost;
  }
  return n;
}

// --- EventLineLimiter ---

std::string EventLineLimiter::line(const Event& e) {
  std::lock_guard lock(mutex_);
  auto it = std::find_if(components_.begin(), components_.end(),
                         [&](const auto& p) { return p.first == e.component; });
  if (it == components_.end()) {
    components_.emplace_back(e.component, PerComponent{});
    it = components_.end() - 1;
  }
  PerComponent& c = it->second;
  const Nanos t = e.detected_ns;
  if (c.last_line != 0 && t - c.last_line < interval_ns_) {
    ++c.pending;
    ++folded_;
    return {};
  }
  std::string s = format_event(e);
  if (c.pending > 0) {
    s += fmt::format(" (+{} more event{} since the previous line)", c.pending,
                     c.pending == 1 ? "" : "s");
  }
  c.pending = 0;
  c.last_line = t != 0 ? t : 1;
  return s;
}

std::uint64_t EventLineLimiter::folded() const {
  std::lock_guard lock(mutex_);
  return folded_;
}

}  // namespace vigil::supervisor
