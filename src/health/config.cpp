#include "vigil/health/config.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "vigil/health/checkpoint.hpp"
#include "vigil/health/report.hpp"

namespace vigil::health {

std::string to_string(const CheckpointRef& ref) {
  return ref.checkpoint.empty() ? ref.entity + " (cycles)" : ref.entity + "." + ref.checkpoint;
}

const char* to_string(SupervisionStatus s) noexcept {
  switch (s) {
    case SupervisionStatus::Ok:
      return "ok";
    case SupervisionStatus::Failed:
      return "failed";
    case SupervisionStatus::Expired:
      return "expired";
    case SupervisionStatus::Deactivated:
      return "deactivated";
  }
  return "?";
}

const char* to_string(SupervisionKind k) noexcept {
  switch (k) {
    case SupervisionKind::Alive:
      return "alive";
    case SupervisionKind::Deadline:
      return "deadline";
    case SupervisionKind::Logical:
      return "logical";
  }
  return "?";
}

const char* to_string(FailureKind k) noexcept {
  switch (k) {
    case FailureKind::None:
      return "none";
    case FailureKind::TooFewIndications:
      return "too_few_indications";
    case FailureKind::TooManyIndications:
      return "too_many_indications";
    case FailureKind::NeverStarted:
      return "never_started";
    case FailureKind::DeadlineTooEarly:
      return "deadline_too_early";
    case FailureKind::DeadlineMissed:
      return "deadline_missed";
    case FailureKind::DeadlineRestarted:
      return "deadline_restarted";
    case FailureKind::InvalidTransition:
      return "invalid_transition";
  }
  return "?";
}

namespace {

std::string ms(Nanos t) { return fmt::format("{:g} ms", static_cast<double>(t) / 1e6); }

Error bad(std::string what) { return Error(EINVAL, std::move(what)); }

expected<void, Error> check_ref(const std::string& where, const char* field,
                                const CheckpointRef& r) {
  if (r.entity.empty())
    return unexpected<Error>(bad(fmt::format("{}: {}: entity is empty", where, field)));
  if (r.checkpoint.size() > kMaxCheckpointName) {
    return unexpected<Error>(bad(fmt::format("{}: {}: checkpoint name '{}' is longer than {} bytes",
                                             where, field, r.checkpoint, kMaxCheckpointName)));
  }
  return {};
}

expected<void, Error> check_alive(const AliveSupervisionConfig& c) {
  const std::string where = fmt::format("alive '{}'", c.name);
  if (auto ok = check_ref(where, "checkpoint", c.checkpoint); !ok) return ok;
  if (c.reference_cycle_ns < kNanosPerMicro) {
    return unexpected<Error>(bad(fmt::format(
        "{}: reference_cycle_ns must be at least 1 us (is {} ns)", where, c.reference_cycle_ns)));
  }
  if (c.min_margin > c.expected_indications) {
    return unexpected<Error>(bad(fmt::format("{}: min_margin ({}) > expected_indications ({})",
                                             where, c.min_margin, c.expected_indications)));
  }
  if (c.expected_indications == 0 && c.max_margin == 0) {
    return unexpected<Error>(
        bad(fmt::format("{}: expected_indications and max_margin are both 0: any indication "
                        "would fail",
                        where)));
  }
  if (c.startup_grace_ns < 0) {
    return unexpected<Error>(bad(fmt::format("{}: startup_grace_ns is negative", where)));
  }
  return {};
}

expected<void, Error> check_deadline(const DeadlineSupervisionConfig& c) {
  const std::string where = fmt::format("deadline '{}'", c.name);
  if (auto ok = check_ref(where, "start", c.start); !ok) return ok;
  if (auto ok = check_ref(where, "end", c.end); !ok) return ok;
  if (c.start == c.end) {
    return unexpected<Error>(bad(
        fmt::format("{}: start and end are the same checkpoint ({})", where, to_string(c.start))));
  }
  if (c.max_ns <= 0) {
    return unexpected<Error>(
        bad(fmt::format("{}: max_ns must be positive (is {} ns)", where, c.max_ns)));
  }
  if (c.min_ns < 0 || c.min_ns > c.max_ns) {
    return unexpected<Error>(bad(fmt::format("{}: min_ns ({}) > max_ns ({}) or negative", where,
                                             ms(c.min_ns), ms(c.max_ns))));
  }
  return {};
}

expected<void, Error> check_logical(const LogicalSupervisionConfig& c) {
  const std::string where = fmt::format("logical '{}'", c.name);
  if (c.initial.empty()) {
    return unexpected<Error>(bad(fmt::format("{}: no initial checkpoint", where)));
  }
  if (c.transitions.empty()) {
    return unexpected<Error>(bad(fmt::format("{}: no transition", where)));
  }
  std::vector<CheckpointRef> nodes;
  const auto index = [&](const CheckpointRef& r) {
    const auto it = std::find(nodes.begin(), nodes.end(), r);
    if (it != nodes.end()) return static_cast<std::size_t>(it - nodes.begin());
    nodes.push_back(r);
    return nodes.size() - 1;
  };
  std::vector<std::pair<std::size_t, std::size_t>> edges;
  for (const auto& t : c.transitions) {
    if (auto ok = check_ref(where, "transition from", t.from); !ok) return ok;
    if (auto ok = check_ref(where, "transition to", t.to); !ok) return ok;
    edges.emplace_back(index(t.from), index(t.to));
  }
  const std::size_t named = nodes.size();
  for (const auto& r : c.initial) {
    if (auto ok = check_ref(where, "initial", r); !ok) return ok;
    if (index(r) >= named) {
      return unexpected<Error>(
          bad(fmt::format("{}: initial checkpoint {} is in no transition", where, to_string(r))));
    }
  }
  for (const auto& r : c.final) {
    if (auto ok = check_ref(where, "final", r); !ok) return ok;
    if (index(r) >= named) {
      return unexpected<Error>(
          bad(fmt::format("{}: final checkpoint {} is in no transition", where, to_string(r))));
    }
  }
  // Every checkpoint must be reachable from an initial one.
  std::vector<char> seen(nodes.size(), 0);
  std::vector<std::size_t> todo;
  for (const auto& r : c.initial) {
    const std::size_t i = index(r);
    if (seen[i] == 0) {
      seen[i] = 1;
      todo.push_back(i);
    }
  }
  while (!todo.empty()) {
    const std::size_t n = todo.back();
    todo.pop_back();
    for (const auto& [from, to] : edges) {
      if (from == n && seen[to] == 0) {
        seen[to] = 1;
        todo.push_back(to);
      }
    }
  }
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (seen[i] == 0) {
      return unexpected<Error>(
          bad(fmt::format("{}: checkpoint {} is unreachable from every initial checkpoint", where,
                          to_string(nodes[i]))));
    }
  }
  return {};
}

}  // namespace

expected<void, Error> validate(const HealthConfig& config) {
  std::set<std::string, std::less<>> names;
  const auto name_ok = [&](const char* kind, const std::string& name) -> expected<void, Error> {
    if (name.empty())
      return unexpected<Error>(bad(fmt::format("{} supervision without a name", kind)));
    if (!names.insert(name).second) {
      return unexpected<Error>(bad(fmt::format("{} '{}': the name is used twice", kind, name)));
    }
    return {};
  };
  for (const auto& c : config.alive) {
    if (auto ok = name_ok("alive", c.name); !ok) return ok;
    if (auto ok = check_alive(c); !ok) return ok;
  }
  for (const auto& c : config.deadline) {
    if (auto ok = name_ok("deadline", c.name); !ok) return ok;
    if (auto ok = check_deadline(c); !ok) return ok;
  }
  for (const auto& c : config.logical) {
    if (auto ok = name_ok("logical", c.name); !ok) return ok;
    if (auto ok = check_logical(c); !ok) return ok;
  }
  if (config.settle_ns < 0) return unexpected<Error>(bad("settle_ns is negative"));
  return {};
}

}  // namespace vigil::health
