#include "vigil/service/reactions.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <exception>
#include <typeinfo>
#include <utility>

#include "vigil/export/systemd_notify.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/safe_state.hpp"

namespace vigil::service {

using monitor::StatusLevel;
using supervisor::EventSeverity;

namespace {

std::string frame_text(const can::Frame& f) {
  std::string s = fmt::format("{:03X} [{}]", f.id, f.length);
  for (std::size_t i = 0; i < f.length && i < f.data.size(); ++i) {
    s += fmt::format(" {:02X}", f.data[i]);
  }
  return s;
}

bool reaches(StatusLevel level, StatusLevel trigger) {
  return static_cast<int>(level) >= static_cast<int>(trigger);
}

}  // namespace

Reactions::Reactions(ReactionsOptions options) : options_(options), dry_run_(options.dry_run) {}

Reactions::~Reactions() { stop(); }

void Reactions::add_handler(std::string name, ReactionHandler handler, Nanos budget_ns) {
  handlers_[std::move(name)] = {std::move(handler), budget_ns};
}

void Reactions::add_can_writer(std::string name, CanWriter writer) {
  writers_[std::move(name)] = std::move(writer);
}

bool Reactions::has_handler(std::string_view name) const {
  return handlers_.find(name) != handlers_.end();
}
bool Reactions::has_can_writer(std::string_view name) const {
  return writers_.find(name) != writers_.end();
}

expected<void, Error> Reactions::add(Reaction r) {
  auto fail = [&](std::string what) {
    return unexpected(Error{fmt::format("reaction '{}': {}", r.name, what)});
  };
  if (r.name.empty()) return unexpected(Error{"a reaction needs a name"});
  for (const Reaction& o : reactions_) {
    if (o.name == r.name) return fail("a reaction of that name exists");
  }
  if (r.on.unit.empty() == !r.on.event.has_value()) {
    return fail("name one trigger: a unit and its status, or an event kind");
  }
  if (r.on.event && *r.on.event == supervisor::EventKind::Reaction) {
    return fail("a reaction cannot fire on reaction events");
  }
  if (!r.on.component.empty() && !r.on.event) return fail("`component` is for event triggers");
  if (!r.on.unit.empty() && r.on.status == StatusLevel::Ok) {
    return fail("a status trigger needs WARN, ERROR or STALE");
  }
  if (!r.safe_state && r.can.empty() && !r.watchdog && r.handlers.empty()) {
    return fail("no action (safe_state, can, watchdog or handlers)");
  }
  for (const std::string& h : r.handlers) {
    if (!has_handler(h)) return fail(fmt::format("no handler named '{}' is registered", h));
  }
  for (const CanAction& c : r.can) {
    if (!has_can_writer(c.writer)) {
      return fail(fmt::format("no CAN writer named '{}' is registered", c.writer));
    }
  }
  if (r.min_interval_ns < 0) return fail("min_interval must not be negative");
  const std::lock_guard lock(mutex_);
  reactions_.push_back(std::move(r));
  per_.emplace_back();
  return {};
}

expected<void, Error> Reactions::start(supervisor::EventHub& events,
                                       exporter::SystemdNotifyOutput* systemd) {
  systemd_ = systemd;
  if (reactions_.empty() || thread_.joinable()) return {};
  {
    const std::lock_guard lock(mutex_);
    stopping_ = false;
  }
  platform::ThreadConfig tc;
  tc.name = "vigil-react";
  tc.stack_bytes = options_.stack_bytes;
  tc.policy = options_.policy;
  tc.priority = options_.priority;
  auto t = platform::Thread::spawn(tc, [this] { run(); });
  realtime_ = t.has_value() && options_.policy == platform::SchedPolicy::Fifo;
  if (!t && options_.policy == platform::SchedPolicy::Fifo) {
    tc.policy = platform::SchedPolicy::Other;  // refused: run, and say so in the unit
    tc.priority = 0;
    t = platform::Thread::spawn(tc, [this] { run(); });
  }
  if (!t) return unexpected(Error{"reactions: " + t.error().message});
  thread_ = std::move(*t);
  const bool wants_events = std::any_of(reactions_.begin(), reactions_.end(),
                                        [](const Reaction& r) { return r.on.event.has_value(); });
  events_ = &events;
  if (wants_events) {
    // The dispatcher that takes the immediate actions runs as the reaction thread does.
    subscription_ = events.subscribe([this](const supervisor::Event& e) { on_event(e); }, 0,
                                     options_.policy, options_.priority);
  }
  return {};
}

void Reactions::stop() {
  if (subscription_ != 0 && events_ != nullptr) {
    events_->unsubscribe(subscription_);
    subscription_ = 0;
  }
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Reactions::on_event(const supervisor::Event& e) {
  if (e.kind == supervisor::EventKind::Reaction) return;  // never on its own events
  for (std::size_t i = 0; i < reactions_.size(); ++i) {
    const ReactionTrigger& on = reactions_[i].on;
    if (!on.event || *on.event != e.kind) continue;
    if (!on.component.empty() && on.component != e.component) continue;
    ReactionContext c;
    c.unit = e.component;
    c.cause = fmt::format("{} {}", e.component, supervisor::to_string(e.kind));
    if (!e.detail.empty()) c.cause += ": " + e.detail;
    c.fault_ns = e.fault_ns > 0 ? e.fault_ns : e.detected_ns;
    c.event = e;
    fire(i, std::move(c));
  }
}

void Reactions::on_reports(const monitor::ReportSet& reports) {
  for (std::size_t i = 0; i < reactions_.size(); ++i) {
    const ReactionTrigger& on = reactions_[i].on;
    if (on.unit.empty()) continue;
    const monitor::Report* r = reports.find(on.unit);
    if (r == nullptr) continue;  // not (yet) a unit of this cycle: nothing changed
    const StatusLevel now = r->status.level();
    StatusLevel before;
    {
      const std::lock_guard lock(mutex_);
      before = per_[i].shown;
      per_[i].shown = now;
    }
    if (!reaches(now, on.status) || reaches(before, on.status)) continue;
    ReactionContext c;
    c.unit = on.unit;
    c.status = now;
    c.cause = fmt::format("{} {}", on.unit, monitor::to_string(now));
    if (!r->status.messages().empty()) c.cause += ": " + r->status.messages().front().text;
    if (!r->caused_by.empty()) {
      c.cause += " (caused by ";
      for (std::size_t k = 0; k < r->caused_by.size(); ++k) {
        c.cause += (k > 0 ? ", " : "") + r->caused_by[k];
      }
      c.cause += ")";
    }
    c.fault_ns = reports.time_ns;
    fire(i, std::move(c));
  }
}

void Reactions::publish(const ReactionContext& c, EventSeverity severity, std::string detail,
                        Nanos action_ns) {
  if (events_ == nullptr) return;
  supervisor::Event e;
  e.kind = supervisor::EventKind::Reaction;
  e.severity = severity;
  e.component = "reaction " + c.reaction;
  e.fault_ns = c.fault_ns;
  e.detected_ns = action_ns;
  e.cycle = c.event ? c.event->cycle : 0;
  e.pid = c.event ? c.event->pid : 0;
  e.detail = std::move(detail);
  events_->publish(std::move(e));
}

void Reactions::fire(std::size_t index, ReactionContext c) {
  const Reaction& r = reactions_[index];
  const Nanos now = platform::now_ns();
  c.reaction = r.name;
  c.triggered_ns = now;
  c.dry_run = dry_run();
  bool limited = false;
  {
    const std::lock_guard lock(mutex_);
    PerReaction& p = per_[index];
    if (r.min_interval_ns > 0 && p.last_fired >= 0 && now - p.last_fired < r.min_interval_ns) {
      ++stats_.rate_limited;
      if (p.limited_reported) return;
      p.limited_reported = true;
      limited = true;
    } else {
      p.last_fired = now;
      p.limited_reported = false;
      ++stats_.fired;
    }
  }
  const std::string& on = c.cause;
  if (limited) {
    publish(c, EventSeverity::Info,
            fmt::format("rate-limited (fired less than {} ago), for {}",
                        monitor::format_nanos(static_cast<double>(r.min_interval_ns)), c.cause),
            now);
    return;
  }
  const char* const would = c.dry_run ? "dry run: would " : "";
  auto count = [&](bool failed) {
    const std::lock_guard lock(mutex_);
    ++stats_.actions;
    if (failed) ++stats_.failed;
  };

  if (r.safe_state) {
    bool fresh = true;
    if (!c.dry_run) fresh = request_safe_state(fmt::format("reaction {}: {}", r.name, c.cause));
    const Nanos t = platform::now_ns();
    count(false);
    publish(c, c.dry_run ? EventSeverity::Info : EventSeverity::Warn,
            fresh ? fmt::format("{}request the safe state, for {}", would, c.cause)
                  : fmt::format("the safe state was already requested (#{}), for {}",
                                safe_state_generation(), c.cause),
            t);
  }
  for (const CanAction& a : r.can) {
    bool ok = true;
    if (!c.dry_run) {
      const auto w = writers_.find(a.writer);
      try {
        ok = w != writers_.end() && w->second(a.frame);
      } catch (...) {
        ok = false;
      }
    }
    const Nanos t = platform::now_ns();
    count(!ok);
    publish(c, ok ? EventSeverity::Info : EventSeverity::Warn,
            ok ? fmt::format("{}send CAN frame {} through {}, for {}", would, frame_text(a.frame),
                             a.writer, on)
               : fmt::format("CAN writer {} refused frame {}, for {}", a.writer,
                             frame_text(a.frame), on),
            t);
  }
  if (r.watchdog) {
    bool ok = c.dry_run;
    if (!c.dry_run && systemd_ != nullptr) ok = systemd_->trigger_watchdog();
    const Nanos t = platform::now_ns();
    count(!ok);
    publish(c, ok ? EventSeverity::Info : EventSeverity::Warn,
            ok ? fmt::format("{}trigger the outer watchdog (WATCHDOG=trigger), for {}", would, on)
            : systemd_ == nullptr
                ? fmt::format("no outer watchdog to trigger (NOTIFY_SOCKET is not set), for {}", on)
                : fmt::format("WATCHDOG=trigger could not be sent, for {}", on),
            t);
  }
  for (const std::string& h : r.handlers) {
    if (c.dry_run) {
      count(false);
      publish(c, EventSeverity::Info, fmt::format("dry run: would call handler {}, for {}", h, on),
              platform::now_ns());
      continue;
    }
    const auto it = handlers_.find(h);
    if (it == handlers_.end()) continue;  // add() checked
    bool dropped = false;
    {
      const std::lock_guard lock(mutex_);
      if (queue_.size() >= options_.queue_capacity || !thread_.joinable()) {
        ++stats_.dropped;
        dropped = true;
      } else {
        const Nanos budget = it->second.second > 0 ? it->second.second : options_.default_budget_ns;
        queue_.push_back({h, it->second.first, budget, c});
      }
    }
    if (dropped) {
      publish(c, EventSeverity::Warn,
              fmt::format("handler {} not called, for {}: {} calls already wait (the reaction "
                          "thread is busy)",
                          h, on, options_.queue_capacity),
              platform::now_ns());
    } else {
      wake_.notify_one();
    }
  }
}

void Reactions::run() {
  for (;;) {
    Call call;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      call = std::move(queue_.front());
      queue_.pop_front();
      running_handler_ = call.handler;
      running_budget_ = call.budget_ns;
      running_since_ = platform::now_ns();
    }
    const Nanos start = platform::now_ns();
    std::string failure;
    try {
      call.fn(call.context);
    } catch (const std::exception& e) {
      failure = fmt::format("threw {}: {}", typeid(e).name(), e.what());
    } catch (...) {
      failure = "threw an exception that is not a std::exception";
    }
    const Nanos end = platform::now_ns();
    const Nanos ran = end - start;
    const bool over = ran > call.budget_ns;
    {
      const std::lock_guard lock(mutex_);
      running_handler_.clear();
      ++stats_.handler_calls;
      ++stats_.actions;
      if (!failure.empty()) ++stats_.failed;
      if (over) ++stats_.over_budget;
    }
    const std::string& on = call.context.cause;
    std::string detail = fmt::format("handler {} ran {}", call.handler,
                                     monitor::format_nanos(static_cast<double>(ran)));
    if (over) {
      detail += fmt::format(", over its {} budget",
                            monitor::format_nanos(static_cast<double>(call.budget_ns)));
    }
    if (!failure.empty()) detail += "; it " + failure;
    detail += ", for " + on;
    // The event's latency is the handler's start after the fault.
    publish(call.context, failure.empty() && !over ? EventSeverity::Info : EventSeverity::Warn,
            std::move(detail), start);
  }
}

ReactionStats Reactions::stats() const {
  const std::lock_guard lock(mutex_);
  return stats_;
}

monitor::Report Reactions::unit(Nanos now) const {
  using monitor::Field;
  monitor::Report r;
  r.kind = monitor::ReportKind::Unit;
  r.unit_kind = "reactions";
  r.name = std::string(kUnitName);
  const std::lock_guard lock(mutex_);
  const bool busy = !running_handler_.empty();
  r.state_label = !thread_.joinable() ? "not running" : busy ? "running a handler" : "idle";
  if (busy && now - running_since_ > running_budget_) {
    r.merge(StatusLevel::Error,
            fmt::format("handler {} has run for {} (budget {})", running_handler_,
                        monitor::format_nanos(static_cast<double>(now - running_since_)),
                        monitor::format_nanos(static_cast<double>(running_budget_))));
  }
  if (stats_.dropped > 0) {
    r.merge(StatusLevel::Warn, fmt::format("{} handler calls dropped", stats_.dropped));
  }
  r.add_field(Field::of_count("reactions", reactions_.size()));
  r.add_field(Field::of_count("fired", stats_.fired));
  r.add_field(Field::of_count("actions", stats_.actions));
  r.add_field(Field::of_count("rate_limited", stats_.rate_limited));
  r.add_field(Field::of_count("failed", stats_.failed));
  r.add_field(Field::of_count("over_budget", stats_.over_budget));
  r.add_field(Field::of_count("dropped", stats_.dropped));
  r.add_field(Field::of_count("queued", queue_.size()));
  r.add_field(Field::of_text("safe_state", safe_state_requested() ? "requested" : "no"));
  if (dry_run()) r.add_field(Field::of_text("mode", "dry run"));
  r.add_field(Field::of_text("policy", realtime_ ? fmt::format("FIFO {}", options_.priority)
                                       : options_.policy == platform::SchedPolicy::Fifo
                                           ? "OTHER (FIFO refused)"
                                           : "OTHER"));
  return r;
}

}  // namespace vigil::service
