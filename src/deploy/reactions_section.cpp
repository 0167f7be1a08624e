#include "vigil/deploy/reactions_section.hpp"

#include <fmt/format.h>

#include <map>
#include <span>
#include <utility>

#include "vigil/config/error.hpp"

namespace vigil::deploy {

namespace {

constexpr Nanos kDay = 86400 * kNanosPerSecond;

constexpr config::EnumName<monitor::StatusLevel> kLevels[] = {
    {"WARN", monitor::StatusLevel::Warn},
    {"ERROR", monitor::StatusLevel::Error},
    {"STALE", monitor::StatusLevel::Stale}};

void trigger(const config::Node& on, service::ReactionTrigger& t) {
  if (!on.is_mapping()) {
    on.error("expected a mapping: {unit: NAME, status: ERROR} or {event: KIND, component: NAME}");
    return;
  }
  on.reject_unknown_keys({"unit", "status", "event", "component"});
  const bool unit = on.has("unit");
  const bool event = on.has("event");
  if (unit == event) {
    on.error("name one trigger: `unit` (with `status`) or `event` (with `component`)");
    return;
  }
  if (unit) {
    t.unit = on.required<std::string>("unit", config::non_empty());
    t.status = on.optional_enum("status", monitor::StatusLevel::Error, kLevels);
    if (on.has("component")) on["component"].error("`component` is for event triggers");
    return;
  }
  if (on.has("status")) on["status"].error("`status` is for unit triggers");
  const config::Node k = on["event"];
  const std::string kind = k.get<std::string>(config::non_empty());
  if (kind.empty()) return;
  if (const auto parsed = supervisor::parse_event_kind(kind); !parsed) {
    const std::vector<std::string_view> names = supervisor::event_kind_names();
    std::string msg = fmt::format("unknown event kind '{}'", kind);
    if (const auto near = config::closest_match(kind, std::span<const std::string_view>(names))) {
      msg += fmt::format("; did you mean '{}'?", *near);
    }
    k.error(msg);
  } else if (*parsed == supervisor::EventKind::Reaction) {
    k.error("a reaction cannot fire on reaction events");
  } else {
    t.event = parsed;
  }
  t.component = on.optional<std::string>("component", "");
}

service::CanAction can_action(const config::Node& n) {
  service::CanAction a;
  if (!n.is_mapping()) {
    n.error("expected a mapping: {writer: NAME, id: 0x000, data: [0x01, 0x05]}");
    return a;
  }
  n.reject_unknown_keys({"writer", "id", "extended", "data"});
  a.writer = n.required<std::string>("writer", config::non_empty());
  const bool extended = n.optional("extended", false);
  const std::uint32_t max = extended ? 0x1FFFFFFFU : 0x7FFU;
  const auto id =
      n.required<std::uint32_t>("id", [max](std::uint32_t v) -> std::optional<std::string> {
        if (v > max) return fmt::format("must be at most {:#x}", max);
        return std::nullopt;
      });
  std::vector<std::uint8_t> bytes;
  if (const config::Node d = n["data"]; d.defined() && !d.is_null()) {
    if (!d.is_sequence()) {
      d.error("expected a list of bytes (0..255)");
    } else if (d.elements().size() > can::kMaxClassicDataLength) {
      d.error(fmt::format("a Classical CAN frame has at most {} data bytes, not {}",
                          can::kMaxClassicDataLength, d.elements().size()));
    } else {
      for (const config::Node& b : d.elements()) {
        bytes.push_back(static_cast<std::uint8_t>(
            b.get<std::uint32_t>([](std::uint32_t v) -> std::optional<std::string> {
              if (v > 255) return "a byte must be 0..255";
              return std::nullopt;
            })));
      }
    }
  }
  a.frame =
      can::Frame::classic(id, bytes, extended ? can::IdFormat::Extended : can::IdFormat::Standard);
  return a;
}

}  // namespace

ReactionsSpec parse_reactions(const config::Node& node) {
  ReactionsSpec spec;
  spec.defined = true;
  if (!node.is_mapping()) {
    node.error("expected a mapping with dry_run, policy, priority and rules");
    return spec;
  }
  node.reject_unknown_keys({"dry_run", "policy", "priority", "rules"});
  spec.dry_run = node.optional("dry_run", false);
  static constexpr config::EnumName<platform::SchedPolicy> kPolicies[] = {
      {"FIFO", platform::SchedPolicy::Fifo}, {"OTHER", platform::SchedPolicy::Other}};
  spec.policy = node.optional_enum("policy", platform::SchedPolicy::Other, kPolicies);
  if (spec.policy == platform::SchedPolicy::Fifo) {
    spec.priority = node.required<int>("priority", config::in_range(1, 99));
  } else {
    spec.priority = node.optional("priority", 0, config::in_range(0, 0));
  }
  const config::Node rules = node["rules"];
  if (!rules.defined() || rules.is_null()) return spec;
  if (!rules.is_sequence()) {
    rules.error("expected a list of reactions");
    return spec;
  }
  std::map<std::string, int, std::less<>> names;
  for (const config::Node& n : rules.elements()) {
    if (!n.is_mapping()) {
      n.error("expected a mapping: {name, on, safe_state, can, watchdog, handlers, min_interval}");
      continue;
    }
    n.reject_unknown_keys(
        {"name", "on", "safe_state", "can", "watchdog", "handlers", "min_interval"});
    service::Reaction r;
    r.name = n.required<std::string>("name", config::non_empty());
    if (!r.name.empty()) {
      if (const auto [it, fresh] = names.emplace(r.name, n["name"].line()); !fresh) {
        n["name"].error(
            fmt::format("'{}' is configured twice (first at line {})", r.name, it->second));
      }
    }
    trigger(n.at("on"), r.on);
    r.safe_state = n.optional("safe_state", false);
    r.watchdog = n.optional("watchdog", false);
    if (const config::Node c = n["can"]; c.defined() && !c.is_null()) {
      if (!c.is_sequence()) {
        c.error("expected a list of frames");
      } else {
        for (const config::Node& f : c.elements()) r.can.push_back(can_action(f));
      }
    }
    if (const config::Node h = n["handlers"]; h.defined() && !h.is_null()) {
      if (!h.is_sequence()) {
        h.error("expected a list of handler names");
      } else {
        for (const config::Node& e : h.elements()) {
          r.handlers.push_back(e.get<std::string>(config::non_empty()));
        }
      }
    }
    r.min_interval_ns =
        n.optional_duration("min_interval", r.min_interval_ns, config::duration_in_range(0, kDay));
    if (!r.safe_state && !r.watchdog && r.can.empty() && r.handlers.empty() && !n.has_errors()) {
      n.error("a reaction needs an action: safe_state, can, watchdog or handlers");
    }
    spec.rules.push_back(std::move(r));
    spec.nodes.push_back(n);
  }
  return spec;
}

}  // namespace vigil::deploy
