#include "vigil/deploy/health_section.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <utility>

#include "vigil/config/error.hpp"
#include "vigil/health/checkpoint.hpp"

namespace vigil::deploy {

namespace {

constexpr Nanos kHour = 3600 * kNanosPerSecond;

class Parser {
 public:
  Parser(HealthSpec& spec, std::span<const std::string> components)
      : spec_(spec), components_(components) {}

  void parse(const config::Node& h) {
    if (!h.is_mapping()) {
      h.error("expected a mapping with alive, deadline and logical supervisions");
      return;
    }
    h.reject_unknown_keys({"alive", "deadline", "logical", "settle", "history"});
    health::HealthConfig& c = spec_.config;
    c.settle_ns = h.optional_duration("settle", c.settle_ns,
                                      config::duration_in_range(0, 10 * kNanosPerMilli));
    c.history = h.optional<std::uint32_t>("history", c.history, config::in_range(1U, 64U));
    for (const config::Node& n : list(h, "alive")) parse_alive(n);
    for (const config::Node& n : list(h, "deadline")) parse_deadline(n);
    for (const config::Node& n : list(h, "logical")) parse_logical(n);
  }

 private:
  // The elements of list `key` (an error when it is not a list).
  static std::vector<config::Node> list(const config::Node& h, std::string_view key) {
    const config::Node l = h[key];
    if (!l.defined() || l.is_null()) return {};
    if (!l.is_sequence()) {
      l.error(fmt::format("expected a list of {} supervisions", key));
      return {};
    }
    return l.elements();
  }

  // `name`: unique among every supervision.
  std::string name(const config::Node& n) {
    std::string s = n.required<std::string>("name", config::non_empty());
    if (s.empty()) return s;
    if (const auto [it, fresh] = names_.emplace(s, n["name"]); !fresh) {
      n["name"].error(fmt::format("supervision '{}' is defined twice (first at line {})", s,
                                  it->second.line()));
    }
    return s;
  }

  // A checkpoint reference: "component.checkpoint", "component", or {component, checkpoint}.
  health::CheckpointRef reference(const config::Node& n) {
    health::CheckpointRef ref;
    if (n.is_mapping()) {
      n.reject_unknown_keys({"component", "checkpoint"});
      ref.entity = n.required<std::string>("component", config::non_empty());
      ref.checkpoint = n.optional<std::string>("checkpoint", "");
      check_entity(n["component"], ref.entity);
    } else {
      const std::string text = n.get<std::string>(config::non_empty());
      if (text.empty()) return ref;
      ref = split(text);
      check_entity(n, ref.entity);
    }
    if (ref.checkpoint.size() > health::kMaxCheckpointName) {
      n.error(fmt::format("checkpoint name '{}' is longer than {} bytes", ref.checkpoint,
                          health::kMaxCheckpointName));
    }
    if (!ref.entity.empty()) spec_.references.push_back({ref, n});
    return ref;
  }

  // "a.b.c" with components known: the longest component name that is the text or a prefix of
  // it followed by a dot; otherwise the text before the first dot.
  [[nodiscard]] health::CheckpointRef split(const std::string& text) const {
    std::size_t best = 0;
    for (const std::string& c : components_) {
      if (c.size() <= best) continue;
      if (text == c || (text.size() > c.size() && text.starts_with(c) && text[c.size()] == '.')) {
        best = c.size();
      }
    }
    if (best > 0) {
      return best == text.size()
                 ? health::CheckpointRef(text)
                 : health::CheckpointRef(text.substr(0, best), text.substr(best + 1));
    }
    const std::size_t dot = text.find('.');
    if (dot == std::string::npos) return {text};
    return {text.substr(0, dot), text.substr(dot + 1)};
  }

  void check_entity(const config::Node& n, const std::string& entity) const {
    if (components_.empty() || entity.empty()) return;
    if (std::find(components_.begin(), components_.end(), entity) != components_.end()) return;
    std::vector<std::string_view> names(components_.begin(), components_.end());
    std::string msg = fmt::format("no component named '{}'", entity);
    if (const auto near = config::closest_match(entity, std::span<const std::string_view>(names))) {
      msg += fmt::format("; did you mean '{}'?", *near);
    } else {
      msg += fmt::format(" (components: {})", fmt::join(names, ", "));
    }
    n.error(std::move(msg));
  }

  // The checks of health::validate() on one supervision, reported at its node.
  template <class Config>
  static void validate_one(const config::Node& n, Config one,
                           std::vector<Config> health::HealthConfig::*list) {
    health::HealthConfig single;
    (single.*list).push_back(std::move(one));
    if (auto ok = health::validate(single); !ok) n.error(ok.error().message);
  }

  void parse_alive(const config::Node& n) {
    n.reject_unknown_keys({"name", "checkpoint", "reference_cycle", "expected", "min_margin",
                           "max_margin", "tolerance", "startup_grace"});
    health::AliveSupervisionConfig a;
    a.name = name(n);
    a.checkpoint = reference(n.at("checkpoint"));
    a.reference_cycle_ns =
        n.required_duration("reference_cycle", config::duration_in_range(1, kHour));
    a.expected_indications =
        n.optional<std::uint32_t>("expected", 1, config::in_range(1U, 1'000'000'000U));
    a.min_margin = n.optional<std::uint32_t>("min_margin", 0);
    a.max_margin = n.optional<std::uint32_t>("max_margin", 0);
    a.failed_cycles_tolerance = n.optional<std::uint32_t>("tolerance", 0);
    a.startup_grace_ns = n.optional_duration("startup_grace", a.startup_grace_ns,
                                             config::duration_in_range(0, kHour));
    if (!n.has_errors()) validate_one(n, a, &health::HealthConfig::alive);
    spec_.config.alive.push_back(std::move(a));
  }

  void parse_deadline(const config::Node& n) {
    n.reject_unknown_keys({"name", "start", "end", "min", "max", "tolerance"});
    health::DeadlineSupervisionConfig d;
    d.name = name(n);
    d.start = reference(n.at("start"));
    d.end = reference(n.at("end"));
    d.min_ns = n.optional_duration("min", 0, config::duration_in_range(0, kHour));
    d.max_ns = n.required_duration("max", config::duration_in_range(1, kHour));
    if (!n.has_errors() && d.min_ns > d.max_ns) {
      n["min"].error(fmt::format("min ({} us) is above max ({} us)", d.min_ns / kNanosPerMicro,
                                 d.max_ns / kNanosPerMicro));
    }
    d.failed_tolerance = n.optional<std::uint32_t>("tolerance", 0);
    if (!n.has_errors()) validate_one(n, d, &health::HealthConfig::deadline);
    spec_.config.deadline.push_back(std::move(d));
  }

  // `initial` / `final`: one checkpoint or a list of them.
  std::vector<health::CheckpointRef> references(const config::Node& l) {
    std::vector<health::CheckpointRef> out;
    if (!l.defined() || l.is_null()) return out;
    if (!l.is_sequence()) {
      out.push_back(reference(l));
      return out;
    }
    for (const config::Node& e : l.elements()) out.push_back(reference(e));
    return out;
  }

  // One transition: [from, to], {from, to} or "from -> to".
  health::Transition transition(const config::Node& t) {
    health::Transition tr;
    if (t.is_sequence()) {
      const auto e = t.elements();
      if (e.size() != 2) {
        t.error(fmt::format("a transition is [from, to]: got {} checkpoints", e.size()));
        return tr;
      }
      tr.from = reference(e[0]);
      tr.to = reference(e[1]);
    } else if (t.is_mapping()) {
      t.reject_unknown_keys({"from", "to"});
      tr.from = reference(t.at("from"));
      tr.to = reference(t.at("to"));
    } else {
      const std::string text = t.get<std::string>(config::non_empty());
      const std::size_t arrow = text.find("->");
      if (arrow == std::string::npos) {
        t.error("a transition is [from, to], {from: a, to: b} or \"a -> b\"");
        return tr;
      }
      auto trim = [](const std::string& s) {
        const auto b = s.find_first_not_of(" \t");
        const auto e = s.find_last_not_of(" \t");
        return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
      };
      const std::string from = trim(text.substr(0, arrow));
      const std::string to = trim(text.substr(arrow + 2));
      if (from.empty() || to.empty()) {
        t.error("a transition \"a -> b\" needs a checkpoint on each side");
        return tr;
      }
      tr.from = split(from);
      tr.to = split(to);
      check_entity(t, tr.from.entity);
      check_entity(t, tr.to.entity);
      spec_.references.push_back({tr.from, t});
      spec_.references.push_back({tr.to, t});
    }
    return tr;
  }

  void parse_logical(const config::Node& n) {
    n.reject_unknown_keys({"name", "initial", "final", "transitions", "tolerance"});
    health::LogicalSupervisionConfig l;
    l.name = name(n);
    l.initial = references(n.at("initial"));
    l.final = references(n["final"]);
    const config::Node ts = n.at("transitions");
    if (ts.defined() && !ts.is_sequence()) {
      ts.error("expected a list of transitions ([from, to])");
    } else {
      for (const config::Node& t : ts.elements()) l.transitions.push_back(transition(t));
    }
    l.failed_tolerance = n.optional<std::uint32_t>("tolerance", 0);
    if (!n.has_errors()) validate_one(n, l, &health::HealthConfig::logical);
    spec_.config.logical.push_back(std::move(l));
  }

  HealthSpec& spec_;
  std::span<const std::string> components_;
  std::map<std::string, config::Node, std::less<>> names_;
};

// Each reference to a named checkpoint of `component` that `declared` does not hold, with its
// message.
template <class Fn>
std::size_t each_undeclared(const HealthSpec& spec, std::string_view component,
                            std::span<const std::string> declared, Fn fn) {
  std::size_t n = 0;
  std::vector<std::string_view> names(declared.begin(), declared.end());
  for (const HealthSpec::Reference& r : spec.references) {
    if (r.ref.entity != component || r.ref.checkpoint.empty()) continue;
    if (std::find(declared.begin(), declared.end(), r.ref.checkpoint) != declared.end()) continue;
    std::string msg =
        fmt::format("component '{}' declares no checkpoint '{}'", component, r.ref.checkpoint);
    if (const auto near =
            config::closest_match(r.ref.checkpoint, std::span<const std::string_view>(names))) {
      msg += fmt::format("; did you mean '{}'?", *near);
    } else if (names.empty()) {
      msg += " (it declares none)";
    } else {
      msg += fmt::format(" (it declares: {})", fmt::join(names, ", "));
    }
    fn(r.node, std::move(msg));
    ++n;
  }
  return n;
}

}  // namespace

HealthSpec parse_health(const config::Node& node, std::span<const std::string> components) {
  HealthSpec spec;
  Parser(spec, components).parse(node);
  return spec;
}

std::size_t check_declared(const HealthSpec& spec, std::string_view component,
                           std::span<const std::string> declared) {
  return each_undeclared(spec, component, declared,
                         [](const config::Node& n, std::string msg) { n.error(std::move(msg)); });
}

std::vector<std::string> undeclared_checkpoints(const HealthSpec& spec, std::string_view component,
                                                std::span<const std::string> declared) {
  std::vector<std::string> out;
  each_undeclared(spec, component, declared, [&](const config::Node& n, std::string msg) {
    out.push_back(fmt::format("{}:{}:{}: {}: {}", n.file(), n.line(), n.column(), n.path(), msg));
  });
  return out;
}

}  // namespace vigil::deploy
