#include "vigil/health/engine.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <deque>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

namespace vigil::health {

namespace {

std::string ms(Nanos t) { return fmt::format("{:.3f} ms", static_cast<double>(t) / 1e6); }

enum class InputKind : std::uint8_t { Checkpoint, Activate, Deactivate };

struct Input {
  Nanos time = 0;
  std::uint64_t seq = 0;  // arrival order, for inputs with the same time
  std::uint64_t count = 0;
  int id = -1;
  InputKind kind = InputKind::Checkpoint;
};

enum class Role : std::uint8_t { Alive, DeadlineStart, DeadlineEnd, Logical };

// One supervision a checkpoint takes part in.
struct Use {
  int supervision = 0;
  Role role = Role::Alive;
  int node = 0;  // logical: the checkpoint's node in the graph
};

struct CheckpointNode {
  int entity = 0;
  std::string label;  // "entity.checkpoint" or "entity (cycles)"
  std::vector<Use> uses;
  std::uint64_t last_count = 0;  // cumulative count of the previous report (0: none)
};

struct Entity {
  std::string name;
  bool active = false;
  bool ever_active = false;
  bool released = false;  // deactivated on purpose: not expected to start
  std::vector<int> supervisions;
};

struct Supervision {
  std::string name;
  SupervisionKind kind = SupervisionKind::Alive;
  std::size_t config = 0;  // index in the configuration's list of its kind
  std::vector<int> entities;
  std::uint32_t tolerance = 0;
  SupervisionStatus status = SupervisionStatus::Deactivated;
  std::uint32_t failed = 0;
  std::uint64_t checkpoints = 0;
  std::uint64_t lost = 0;
  std::uint64_t evaluations = 0;
  std::uint64_t failures = 0;
  std::uint64_t expirations = 0;
  bool has_failure = false;
  Failure last;
  // Alive.
  Nanos window_ns = 0;
  Nanos window_end = kNever;
  std::uint64_t window_count = 0;
  std::uint64_t last_window_count = 0;
  bool window_failed = false;
  bool awaiting_start = false;  // the start-up grace period runs
  Nanos grace_ns = 0;
  // Deadline.
  bool started = false;
  Nanos start_time = 0;
  Nanos last_duration = 0;
  Nanos min_duration = 0;
  Nanos max_duration = 0;
  int start_cp = -1;  // alive: its checkpoint
  int end_cp = -1;
  struct Span {
    Nanos start = 0;
    Nanos end = 0;
    FailureKind failure = FailureKind::None;
  };
  std::deque<Span> spans;  // the latest pairs (HealthEngine::kKeptSpans), for traces
  // Logical.
  std::vector<int> nodes;              // node -> checkpoint handle
  std::vector<std::vector<int>> next;  // node -> allowed next nodes
  std::vector<char> initial;           // node -> is initial
  std::vector<char> final;             // node -> is final
  int current = -1;                    // node of the sequence under way (-1: between two)
  bool synced = false;                 // an initial checkpoint was seen since the activation
  std::deque<int> history;             // latest checkpoint handles seen
};

}  // namespace

struct HealthEngine::Impl {
  static constexpr Nanos kMinusInfinity = INT64_MIN;
  HealthConfig config;
  std::vector<Entity> entities;
  std::vector<CheckpointNode> checkpoints;
  std::vector<Supervision> sups;
  std::map<std::string, int, std::less<>> entity_index;
  std::map<std::string, int, std::less<>> checkpoint_index;  // "entity\0checkpoint"
  std::vector<Input> inputs;
  std::uint64_t seq = 0;
  std::vector<Failure> failures;
  bool started = false;
  Nanos origin = 0;
  Nanos now = 0;  // advance()'s now: the detection time of what it finds

  static std::string key(std::string_view entity, std::string_view name) {
    std::string k(entity);
    k.push_back('\0');
    k.append(name);
    return k;
  }

  int add_entity(const std::string& name) {
    if (auto it = entity_index.find(name); it != entity_index.end()) return it->second;
    const int id = static_cast<int>(entities.size());
    entities.push_back(Entity{name, false, false, false, {}});
    entity_index.emplace(name, id);
    return id;
  }

  int add_checkpoint(const CheckpointRef& ref) {
    const std::string k = key(ref.entity, ref.checkpoint);
    if (auto it = checkpoint_index.find(k); it != checkpoint_index.end()) return it->second;
    const int id = static_cast<int>(checkpoints.size());
    CheckpointNode n;
    n.entity = add_entity(ref.entity);
    n.label = to_string(ref);
    checkpoints.push_back(std::move(n));
    checkpoint_index.emplace(k, id);
    return id;
  }

  int add_supervision(std::string name, SupervisionKind kind, std::size_t config_index,
                      std::uint32_t tolerance) {
    Supervision s;
    s.name = std::move(name);
    s.kind = kind;
    s.config = config_index;
    s.tolerance = tolerance;
    sups.push_back(std::move(s));
    return static_cast<int>(sups.size() - 1);
  }

  void use(int sup, int cp, Role role, int node = 0) {
    checkpoints[static_cast<std::size_t>(cp)].uses.push_back(Use{sup, role, node});
    auto& s = sups[static_cast<std::size_t>(sup)];
    const int e = checkpoints[static_cast<std::size_t>(cp)].entity;
    if (std::find(s.entities.begin(), s.entities.end(), e) == s.entities.end()) {
      s.entities.push_back(e);
      entities[static_cast<std::size_t>(e)].supervisions.push_back(sup);
    }
  }

  void build() {
    for (std::size_t i = 0; i < config.alive.size(); ++i) {
      const auto& c = config.alive[i];
      const int s = add_supervision(c.name, SupervisionKind::Alive, i, c.failed_cycles_tolerance);
      sups.back().window_ns = c.reference_cycle_ns;
      sups.back().grace_ns = c.startup_grace_ns;
      sups.back().awaiting_start = c.startup_grace_ns > 0;
      const int cp = add_checkpoint(c.checkpoint);
      sups.back().start_cp = cp;  // the alive checkpoint
      use(s, cp, Role::Alive);
    }
    for (std::size_t i = 0; i < config.deadline.size(); ++i) {
      const auto& c = config.deadline[i];
      const int s = add_supervision(c.name, SupervisionKind::Deadline, i, c.failed_tolerance);
      const int a = add_checkpoint(c.start);
      const int b = add_checkpoint(c.end);
      sups.back().start_cp = a;
      sups.back().end_cp = b;
      use(s, a, Role::DeadlineStart);
      use(s, b, Role::DeadlineEnd);
    }
    for (std::size_t i = 0; i < config.logical.size(); ++i) {
      const auto& c = config.logical[i];
      const int s = add_supervision(c.name, SupervisionKind::Logical, i, c.failed_tolerance);
      const auto node_of = [&](const CheckpointRef& ref) {
        const int cp = add_checkpoint(ref);
        auto& sv = sups[static_cast<std::size_t>(s)];
        const auto it = std::find(sv.nodes.begin(), sv.nodes.end(), cp);
        if (it != sv.nodes.end()) return static_cast<int>(it - sv.nodes.begin());
        sv.nodes.push_back(cp);
        sv.next.emplace_back();
        sv.initial.push_back(0);
        sv.final.push_back(0);
        const int node = static_cast<int>(sv.nodes.size() - 1);
        use(s, cp, Role::Logical, node);
        return node;
      };
      for (const auto& t : c.transitions) {
        const int from = node_of(t.from);
        const int to = node_of(t.to);
        auto& next = sups[static_cast<std::size_t>(s)].next[static_cast<std::size_t>(from)];
        if (std::find(next.begin(), next.end(), to) == next.end()) next.push_back(to);
      }
      for (const auto& r : c.initial) {
        sups[static_cast<std::size_t>(s)].initial[static_cast<std::size_t>(node_of(r))] = 1;
      }
      for (const auto& r : c.final) {
        sups[static_cast<std::size_t>(s)].final[static_cast<std::size_t>(node_of(r))] = 1;
      }
    }
  }

  // --- status machine ---------------------------------------------------------------------------

  void fail(Supervision& s, FailureKind kind, int entity, Nanos fault, std::string text) {
    ++s.failures;
    const SupervisionStatus before = s.status;
    if (kind == FailureKind::NeverStarted) {
      s.status = SupervisionStatus::Expired;  // an entity that must run and never did
    } else if (before == SupervisionStatus::Ok || before == SupervisionStatus::Deactivated) {
      if (s.failed < s.tolerance) {
        ++s.failed;
        s.status = SupervisionStatus::Failed;
      } else {
        s.status = SupervisionStatus::Expired;
      }
    } else if (before == SupervisionStatus::Failed) {
      ++s.failed;
      if (s.failed > s.tolerance) s.status = SupervisionStatus::Expired;
    }
    if (s.status == SupervisionStatus::Expired && before != SupervisionStatus::Expired) {
      ++s.expirations;
    }
    Failure f;
    f.supervision = s.name;
    f.kind = s.kind;
    f.failure = kind;
    f.status = s.status;
    f.entity = entity >= 0 ? entities[static_cast<std::size_t>(entity)].name : std::string();
    f.fault_ns = fault;
    f.detected_ns = now;
    f.text = std::move(text);
    s.has_failure = true;
    s.last = f;
    // EXPIRED is latched: what follows is counted, not raised again.
    if (before != SupervisionStatus::Expired) failures.push_back(std::move(f));
  }

  static void pass(Supervision& s) {
    if (s.status != SupervisionStatus::Failed) return;
    if (s.failed <= 1) {
      s.failed = 0;
      s.status = SupervisionStatus::Ok;
    } else {
      --s.failed;
    }
  }

  [[nodiscard]] bool all_active(const Supervision& s) const {
    return std::all_of(s.entities.begin(), s.entities.end(),
                       [&](int e) { return entities[static_cast<std::size_t>(e)].active; });
  }

  void start_supervision(Supervision& s, Nanos t) {
    s.status = SupervisionStatus::Ok;
    s.failed = 0;
    s.awaiting_start = false;
    s.window_end = s.kind == SupervisionKind::Alive ? t + s.window_ns : kNever;
    s.window_count = 0;
    s.window_failed = false;
    s.started = false;
    s.current = -1;
    s.synced = false;
  }

  static void stop_supervision(Supervision& s) {
    s.status = SupervisionStatus::Deactivated;
    s.failed = 0;
    s.awaiting_start = false;
    s.window_end = kNever;
    s.window_count = 0;
    s.window_failed = false;
    s.started = false;
    s.current = -1;
  }

  void on_activate(int e, Nanos t) {
    auto& en = entities[static_cast<std::size_t>(e)];
    if (en.active) return;
    en.active = true;
    en.ever_active = true;
    en.released = false;
    for (const int si : en.supervisions) {
      auto& s = sups[static_cast<std::size_t>(si)];
      if (all_active(s)) start_supervision(s, t);
    }
  }

  void on_deactivate(int e) {
    auto& en = entities[static_cast<std::size_t>(e)];
    en.released = true;
    en.active = false;
    for (const int si : en.supervisions) stop_supervision(sups[static_cast<std::size_t>(si)]);
  }

  // --- checkpoints ------------------------------------------------------------------------------

  void on_checkpoint(int cp, Nanos t, std::uint64_t count) {
    auto& node = checkpoints[static_cast<std::size_t>(cp)];
    auto& en = entities[static_cast<std::size_t>(node.entity)];
    // An entity that reports runs: activated by its first report unless stopped on purpose.
    if (!en.active && !en.ever_active && !en.released) on_activate(node.entity, t);
    // Reports between this one and the previous one that a full port dropped.
    std::uint64_t seen = 1;
    if (count != 0) {
      if (node.last_count != 0 && count > node.last_count) seen = count - node.last_count;
      node.last_count = count;
    }
    if (!en.active) return;
    for (const Use& u : node.uses) {
      auto& s = sups[static_cast<std::size_t>(u.supervision)];
      if (s.status == SupervisionStatus::Deactivated) continue;
      s.checkpoints += seen;
      s.lost += seen - 1;
      switch (u.role) {
        case Role::Alive:
          alive_indications(s, cp, t, seen);
          break;
        case Role::DeadlineStart:
          deadline_start(s, t);
          break;
        case Role::DeadlineEnd:
          deadline_end(s, t);
          break;
        case Role::Logical:
          logical_checkpoint(s, cp, u.node, t, seen > 1);
          break;
      }
    }
  }

  void alive_indications(Supervision& s, int cp, Nanos t, std::uint64_t n) {
    s.window_count += n;
    const auto& c = config.alive[s.config];
    const std::uint64_t most = std::uint64_t{c.expected_indications} + c.max_margin;
    if (!s.window_failed && s.window_count > most) {
      s.window_failed = true;
      fail(s, FailureKind::TooManyIndications, checkpoints[static_cast<std::size_t>(cp)].entity, t,
           fmt::format("{}: {} indications within {} of a {} reference cycle (at most {}: "
                       "expected {} +{})",
                       checkpoints[static_cast<std::size_t>(cp)].label, s.window_count,
                       ms(t - (s.window_end - s.window_ns)), ms(s.window_ns), most,
                       c.expected_indications, c.max_margin));
    }
  }

  static void keep_span(Supervision& s, Nanos start, Nanos end, FailureKind f) {
    s.spans.push_back({start, end, f});
    if (s.spans.size() > HealthEngine::kKeptSpans) s.spans.pop_front();
  }

  void deadline_start(Supervision& s, Nanos t) {
    const auto& c = config.deadline[s.config];
    if (s.started) {
      keep_span(s, s.start_time, t, FailureKind::DeadlineRestarted);
      fail(s, FailureKind::DeadlineRestarted,
           checkpoints[static_cast<std::size_t>(s.start_cp)].entity, t,
           fmt::format("{} again {} after the previous one, before {}",
                       checkpoints[static_cast<std::size_t>(s.start_cp)].label,
                       ms(t - s.start_time), to_string(c.end)));
    }
    s.started = true;
    s.start_time = t;
  }

  void deadline_end(Supervision& s, Nanos t) {
    // An end without a start (its start's deadline passed already, or it was never seen) is
    // not judged again.
    if (!s.started || t < s.start_time) return;
    const auto& c = config.deadline[s.config];
    const Nanos d = t - s.start_time;
    s.started = false;
    ++s.evaluations;
    s.last_duration = d;
    s.min_duration = s.evaluations == 1 ? d : std::min(s.min_duration, d);
    s.max_duration = std::max(s.max_duration, d);
    const int entity = checkpoints[static_cast<std::size_t>(s.end_cp)].entity;
    keep_span(s, s.start_time, t, d < c.min_ns ? FailureKind::DeadlineTooEarly : FailureKind::None);
    if (d < c.min_ns) {
      fail(s, FailureKind::DeadlineTooEarly, entity, t,
           fmt::format("{} -> {} took {} (min {})", to_string(c.start), to_string(c.end), ms(d),
                       ms(c.min_ns)));
    } else {
      pass(s);  // d <= max: a later end was found missing when max passed
    }
  }

  [[nodiscard]] std::string history_text(const Supervision& s) const {
    std::string out;
    for (const int cp : s.history) {
      if (!out.empty()) out += " -> ";
      out += checkpoints[static_cast<std::size_t>(cp)].label;
    }
    return out;
  }

  void logical_checkpoint(Supervision& s, int cp, int node, Nanos t, bool lost_before) {
    const auto un = static_cast<std::size_t>(node);
    // The checkpoints before this one (for a failure's text), then this one.
    const auto remember = [&] {
      s.history.push_back(cp);
      while (s.history.size() > std::max<std::size_t>(config.history, 1)) s.history.pop_front();
    };
    const int after = s.final[un] != 0 ? -1 : node;
    // Activated in the middle of a sequence (its entities start one after the other, or a
    // daemon attaches late): judged from the first initial checkpoint on.
    if (!s.synced) {
      if (s.initial[un] == 0) {
        remember();
        return;
      }
      s.synced = true;
    }
    if (lost_before) {  // reports were lost just before: take this one as the new position
      remember();
      s.current = after;
      return;
    }
    ++s.evaluations;
    const bool valid = s.current < 0
                           ? s.initial[un] != 0
                           : std::find(s.next[static_cast<std::size_t>(s.current)].begin(),
                                       s.next[static_cast<std::size_t>(s.current)].end(),
                                       node) != s.next[static_cast<std::size_t>(s.current)].end();
    if (valid) {
      remember();
      pass(s);
      s.current = after;
      return;
    }
    const std::string last = history_text(s);
    remember();
    std::string allowed;
    const auto add = [&](int n) {
      if (!allowed.empty()) allowed += ", ";
      allowed += checkpoints[static_cast<std::size_t>(s.nodes[static_cast<std::size_t>(n)])].label;
    };
    if (s.current < 0) {
      for (std::size_t n = 0; n < s.nodes.size(); ++n) {
        if (s.initial[n] != 0) add(static_cast<int>(n));
      }
    } else {
      for (const int n : s.next[static_cast<std::size_t>(s.current)]) add(n);
    }
    const std::string seen = checkpoints[static_cast<std::size_t>(cp)].label;
    std::string text =
        s.current < 0 ? fmt::format("{} at the start of a sequence; allowed: {}", seen, allowed)
                      : fmt::format("{} after {}; allowed: {}", seen,
                                    checkpoints[static_cast<std::size_t>(
                                                    s.nodes[static_cast<std::size_t>(s.current)])]
                                        .label,
                                    allowed.empty() ? std::string("none") : allowed);
    if (!last.empty()) text += fmt::format("; last: {}", last);
    s.current = after;  // resynchronise on the checkpoint seen
    fail(s, FailureKind::InvalidTransition, checkpoints[static_cast<std::size_t>(cp)].entity, t,
         std::move(text));
  }

  // --- due times --------------------------------------------------------------------------------

  [[nodiscard]] Nanos grace_end(const Supervision& s) const {
    return started ? origin + s.grace_ns : kNever;
  }

  [[nodiscard]] Nanos due(const Supervision& s) const {
    switch (s.kind) {
      case SupervisionKind::Alive:
        if (s.awaiting_start) return grace_end(s);
        return s.status == SupervisionStatus::Deactivated ? kNever : s.window_end;
      case SupervisionKind::Deadline:
        return s.started ? s.start_time + config.deadline[s.config].max_ns + 1 : kNever;
      case SupervisionKind::Logical:
        return kNever;
    }
    return kNever;
  }

  void fire(Supervision& s, Nanos limit) {
    if (s.kind == SupervisionKind::Deadline) {
      const auto& c = config.deadline[s.config];
      s.started = false;
      ++s.evaluations;
      keep_span(s, s.start_time, s.start_time + c.max_ns, FailureKind::DeadlineMissed);
      fail(
          s, FailureKind::DeadlineMissed, checkpoints[static_cast<std::size_t>(s.end_cp)].entity,
          s.start_time + c.max_ns,
          fmt::format("no {} within {} of {}", to_string(c.end), ms(c.max_ns), to_string(c.start)));
      return;
    }
    // Alive.
    const auto& c = config.alive[s.config];
    const int e = s.entities.front();
    if (s.awaiting_start) {
      s.awaiting_start = false;
      if (entities[static_cast<std::size_t>(e)].ever_active ||
          entities[static_cast<std::size_t>(e)].released) {
        return;
      }
      fail(s, FailureKind::NeverStarted, e, grace_end(s),
           fmt::format("{} has not started within its start-up grace period ({})",
                       entities[static_cast<std::size_t>(e)].name, ms(s.grace_ns)));
      return;
    }
    const std::uint64_t least = c.expected_indications - c.min_margin;
    // One reference cycle ends; then every whole one that passed without an indication.
    std::uint64_t windows = 1;
    if (limit != kNever && limit - s.window_end >= s.window_ns) {
      windows += static_cast<std::uint64_t>((limit - s.window_end) / s.window_ns);
    }
    for (std::uint64_t w = 0; w < windows; ++w) {
      const Nanos end = s.window_end;
      ++s.evaluations;
      s.last_window_count = s.window_count;
      if (!s.window_failed) {
        if (s.window_count < least) {
          fail(s, FailureKind::TooFewIndications, e, end,
               fmt::format("{}: {} indication{} in a {} reference cycle (at least {}: expected "
                           "{} -{})",
                           checkpoints[static_cast<std::size_t>(s.start_cp)].label, s.window_count,
                           s.window_count == 1 ? "" : "s", ms(s.window_ns), least,
                           c.expected_indications, c.min_margin));
        } else {
          pass(s);
        }
      }
      s.window_end += s.window_ns;
      s.window_count = 0;
      s.window_failed = false;
      // Empty windows beyond the tolerance change nothing but counts: skip them in bulk.
      if (s.status == SupervisionStatus::Expired && w + 1 < windows) {
        const std::uint64_t rest = windows - w - 1;
        s.evaluations += rest;
        if (least > 0) s.failures += rest;
        s.last_window_count = 0;
        s.window_end += static_cast<Nanos>(rest) * s.window_ns;
        break;
      }
      if (least == 0 && w + 1 < windows) {  // empty windows pass: no need to walk them
        const std::uint64_t rest = windows - w - 1;
        s.evaluations += rest;
        for (std::uint64_t k = 0; k < rest && s.status == SupervisionStatus::Failed; ++k) pass(s);
        s.last_window_count = 0;
        s.window_end += static_cast<Nanos>(rest) * s.window_ns;
        break;
      }
    }
  }

  // A lower bound of every supervision's due time: lowered whenever one may become earlier
  // (an input applied), raised to the true minimum by a scan. Most inputs then pass without
  // looking at every supervision.
  Nanos min_due = kNever;

  void fire_until(Nanos limit) {
    if (min_due > limit) return;
    for (;;) {
      Supervision* first = nullptr;
      Nanos when = kNever;
      for (auto& s : sups) {
        const Nanos d = due(s);
        if (d < when) {
          when = d;
          first = &s;
        }
      }
      if (first == nullptr || when > limit) {
        min_due = when;
        return;
      }
      fire(*first, limit);
    }
  }

  void lower_due(int entity_or_checkpoint, bool is_entity) {
    const auto lower = [&](int si) {
      min_due = std::min(min_due, due(sups[static_cast<std::size_t>(si)]));
    };
    if (is_entity) {
      for (const int si : entities[static_cast<std::size_t>(entity_or_checkpoint)].supervisions) {
        lower(si);
      }
    } else {
      for (const Use& u : checkpoints[static_cast<std::size_t>(entity_or_checkpoint)].uses) {
        lower(u.supervision);
      }
    }
  }

  void apply(const Input& in) {
    switch (in.kind) {
      case InputKind::Checkpoint: {
        const int e = checkpoints[static_cast<std::size_t>(in.id)].entity;
        const bool was_active = entities[static_cast<std::size_t>(e)].active;
        on_checkpoint(in.id, in.time, in.count);
        if (was_active) {
          lower_due(in.id, false);
        } else {
          lower_due(e, true);  // activated by its first report
        }
        break;
      }
      case InputKind::Activate:
        on_activate(in.id, in.time);
        lower_due(in.id, true);
        break;
      case InputKind::Deactivate:
        on_deactivate(in.id);
        break;
    }
  }

  void advance(Nanos at, Nanos drained_to) {
    if (!started) {
      started = true;
      origin = at;
      min_due = kMinusInfinity;  // grace periods now have an end: scan
    }
    now = at;
    // Inputs are complete only up to when the drain that brought them began: a port drained
    // later in the same pass may still hold an older report than the newest one of a port
    // drained earlier.
    const Nanos horizon = std::min(at, drained_to) - config.settle_ns;
    // Nothing drained can have happened after now: a later time is another clock's (a
    // transition made outside a cycle, stamped with the system clock while the cycles run on a
    // replaced one). Taken as now.
    for (Input& in : inputs) in.time = std::min(in.time, at);
    std::sort(inputs.begin(), inputs.end(), [](const Input& a, const Input& b) {
      return a.time != b.time ? a.time < b.time : a.seq < b.seq;
    });
    std::size_t i = 0;
    for (; i < inputs.size() && inputs[i].time <= horizon; ++i) {
      fire_until(inputs[i].time);
      apply(inputs[i]);
    }
    inputs.erase(inputs.begin(), inputs.begin() + static_cast<std::ptrdiff_t>(i));
    fire_until(horizon);
  }

  [[nodiscard]] Nanos next_deadline() const {
    Nanos when = kNever;
    for (const auto& s : sups) when = std::min(when, due(s));
    // A start is known only once drained: an active deadline supervision waiting for one asks
    // to be drained at least every max_ns, so that the start of a chain is seen before its
    // deadline passes (and the missing end is found when it does).
    Nanos poll = kNever;
    for (const auto& s : sups) {
      if (s.kind == SupervisionKind::Deadline && s.status != SupervisionStatus::Deactivated &&
          !s.started && started) {
        poll = std::min(poll, now + config.deadline[s.config].max_ns);
      }
    }
    for (const auto& in : inputs) when = std::min(when, in.time);
    if (!started) {
      // The grace periods count from the first advance(): ask for one at once.
      for (const auto& s : sups) {
        if (s.awaiting_start) return 0;
      }
    }
    return std::min(poll, when == kNever ? kNever : when + config.settle_ns);
  }

  void queue(InputKind kind, int id, Nanos t, std::uint64_t count) {
    inputs.push_back(Input{t, seq++, count, id, kind});
  }

  [[nodiscard]] SupervisionReport report_of(const Supervision& s) const {
    SupervisionReport r;
    r.name = s.name;
    r.kind = s.kind;
    r.status = s.status;
    for (const int e : s.entities) r.entities.push_back(entities[static_cast<std::size_t>(e)].name);
    r.checkpoints = s.checkpoints;
    r.lost = s.lost;
    r.evaluations = s.evaluations;
    r.failures = s.failures;
    r.failed_count = s.failed;
    r.tolerance = s.tolerance;
    r.expirations = s.expirations;
    r.last_window_count = s.last_window_count;
    r.window_count = s.window_count;
    r.last_duration_ns = s.last_duration;
    r.min_duration_ns = s.min_duration;
    r.max_duration_ns = s.max_duration;
    r.started = s.started;
    if (s.current >= 0) {
      r.current =
          checkpoints[static_cast<std::size_t>(s.nodes[static_cast<std::size_t>(s.current)])].label;
    }
    r.has_failure = s.has_failure;
    r.last_failure = s.last;
    return r;
  }
};

HealthEngine::HealthEngine(HealthConfig config) : impl_(std::make_unique<Impl>()) {
  if (auto ok = validate(config); !ok) throw std::invalid_argument(ok.error().message);
  impl_->config = std::move(config);
  impl_->build();
}
HealthEngine::~HealthEngine() = default;
HealthEngine::HealthEngine(HealthEngine&&) noexcept = default;
HealthEngine& HealthEngine::operator=(HealthEngine&&) noexcept = default;

int HealthEngine::entity(std::string_view name) const {
  const auto it = impl_->entity_index.find(name);
  return it == impl_->entity_index.end() ? -1 : it->second;
}

int HealthEngine::checkpoint(std::string_view entity, std::string_view name) const {
  const auto it = impl_->checkpoint_index.find(Impl::key(entity, name));
  return it == impl_->checkpoint_index.end() ? -1 : it->second;
}

int HealthEngine::entity_of(int checkpoint) const {
  if (checkpoint < 0 || static_cast<std::size_t>(checkpoint) >= impl_->checkpoints.size()) {
    return -1;
  }
  return impl_->checkpoints[static_cast<std::size_t>(checkpoint)].entity;
}

std::size_t HealthEngine::entities() const noexcept { return impl_->entities.size(); }

const std::string& HealthEngine::entity_name(int entity) const {
  return impl_->entities.at(static_cast<std::size_t>(entity)).name;
}

void HealthEngine::start(Nanos now) {
  if (impl_->started) return;
  impl_->started = true;
  impl_->origin = now;
  impl_->min_due = Impl::kMinusInfinity;  // grace periods now have an end: scan
}

void HealthEngine::activate(int entity, Nanos time) {
  if (entity < 0 || static_cast<std::size_t>(entity) >= impl_->entities.size()) return;
  impl_->queue(InputKind::Activate, entity, time, 0);
}

void HealthEngine::deactivate(int entity, Nanos time) {
  if (entity < 0 || static_cast<std::size_t>(entity) >= impl_->entities.size()) return;
  impl_->queue(InputKind::Deactivate, entity, time, 0);
}

void HealthEngine::report(int checkpoint, Nanos time, std::uint64_t count) {
  if (checkpoint < 0 || static_cast<std::size_t>(checkpoint) >= impl_->checkpoints.size()) return;
  impl_->queue(InputKind::Checkpoint, checkpoint, time, count);
}

void HealthEngine::advance(Nanos now) { impl_->advance(now, now); }
void HealthEngine::advance(Nanos now, Nanos drained_to) { impl_->advance(now, drained_to); }

Nanos HealthEngine::next_deadline() const noexcept { return impl_->next_deadline(); }

std::vector<Failure> HealthEngine::take_failures() {
  std::vector<Failure> out;
  out.swap(impl_->failures);
  return out;
}

std::size_t HealthEngine::pending_failures() const noexcept { return impl_->failures.size(); }

std::vector<SupervisionReport> HealthEngine::reports() const {
  std::vector<SupervisionReport> out;
  out.reserve(impl_->sups.size());
  for (const auto& s : impl_->sups) out.push_back(impl_->report_of(s));
  return out;
}

std::vector<DeadlineSpan> HealthEngine::deadline_spans(std::string_view entity, Nanos from) const {
  std::vector<DeadlineSpan> out;
  const Impl& m = *impl_;
  for (const Supervision& s : m.sups) {
    if (s.kind != SupervisionKind::Deadline || s.spans.empty()) continue;
    const auto& start = m.checkpoints[static_cast<std::size_t>(s.start_cp)];
    const auto& end = m.checkpoints[static_cast<std::size_t>(s.end_cp)];
    if (m.entities[static_cast<std::size_t>(start.entity)].name != entity &&
        m.entities[static_cast<std::size_t>(end.entity)].name != entity) {
      continue;
    }
    for (const Supervision::Span& sp : s.spans) {
      if (sp.end < from) continue;
      out.push_back(DeadlineSpan{s.name, start.label, end.label, sp.start, sp.end, sp.failure});
    }
  }
  return out;
}

SupervisionStatus HealthEngine::status(std::string_view name) const {
  for (const auto& s : impl_->sups) {
    if (s.name == name) return s.status;
  }
  return SupervisionStatus::Deactivated;
}

const HealthConfig& HealthEngine::config() const noexcept { return impl_->config; }

}  // namespace vigil::health
