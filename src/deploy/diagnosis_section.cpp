#include "vigil/deploy/diagnosis_section.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <map>
#include <utility>

#include "vigil/config/error.hpp"

namespace vigil::deploy {

namespace {

constexpr Nanos kDay = 86400 * kNanosPerSecond;

constexpr config::EnumName<monitor::AggregateOp> kOps[] = {{"and", monitor::AggregateOp::And},
                                                           {"or", monitor::AggregateOp::Or},
                                                           {"k_of_n", monitor::AggregateOp::KOfN}};

class Parser {
 public:
  explicit Parser(DiagnosisSpec& spec) : spec_(spec) {}

  void parse(const config::Node& d) {
    spec_.defined = true;
    if (!d.is_mapping()) {
      d.error("expected a mapping with startup, hysteresis, units and aggregates");
      return;
    }
    d.reject_unknown_keys({"startup", "hysteresis", "contributor_edges", "units", "aggregates"});
    monitor::DiagnosisConfig& c = spec_.config;
    c.startup_ns = d.optional_duration("startup", c.startup_ns, config::duration_in_range(0, kDay));
    if (const config::Node h = d["hysteresis"]; h.defined()) c.hysteresis = hysteresis(h);
    c.contributor_edges = d.optional("contributor_edges", true);
    for (const config::Node& n : list(d, "units")) unit(n);
    for (const config::Node& n : list(d, "aggregates")) aggregate(n);
    if (d.has_errors()) return;
    // What only the whole graph shows: a cycle, a name used twice.
    if (auto ok = monitor::validate(c); !ok) d.error(ok.error().message);
  }

 private:
  static std::vector<config::Node> list(const config::Node& d, std::string_view key) {
    const config::Node l = d[key];
    if (!l.defined() || l.is_null()) return {};
    if (!l.is_sequence()) {
      l.error(fmt::format("expected a list of {}", key));
      return {};
    }
    return l.elements();
  }

  static monitor::Hysteresis hysteresis(const config::Node& h) {
    h.reject_unknown_keys(
        {"raise_after", "clear_after", "raise_after_cycles", "clear_after_cycles"});
    monitor::Hysteresis out;
    out.raise_after_ns = h.optional_duration("raise_after", 0, config::duration_in_range(0, kDay));
    out.clear_after_ns = h.optional_duration("clear_after", 0, config::duration_in_range(0, kDay));
    const auto cycles = [](std::uint32_t v) -> std::optional<std::string> {
      if (v > 86400) return "must be at most 86400 cycles";
      return std::nullopt;
    };
    out.raise_after_cycles = h.optional<std::uint32_t>("raise_after_cycles", 0, cycles);
    out.clear_after_cycles = h.optional<std::uint32_t>("clear_after_cycles", 0, cycles);
    return out;
  }

  std::string name(const config::Node& n) {
    std::string s = n.required<std::string>("name", config::non_empty());
    if (s.empty()) return s;
    if (const auto [it, fresh] = names_.emplace(s, n["name"].line()); !fresh) {
      n["name"].error(fmt::format("'{}' is configured twice (first at line {})", s, it->second));
    }
    spec_.references.push_back({s, n["name"]});
    return s;
  }

  std::vector<std::string> names(const config::Node& l) {
    std::vector<std::string> out;
    if (!l.defined() || l.is_null()) return out;
    if (!l.is_sequence()) {
      l.error("expected a list of unit names");
      return out;
    }
    for (const config::Node& e : l.elements()) {
      std::string s = e.get<std::string>(config::non_empty());
      if (s.empty()) continue;
      spec_.references.push_back({s, e});
      out.push_back(std::move(s));
    }
    return out;
  }

  void unit(const config::Node& n) {
    n.reject_unknown_keys({"name", "depends_on", "hysteresis", "latch"});
    monitor::DiagnosisUnit u;
    u.name = name(n);
    u.depends_on = names(n["depends_on"]);
    if (const config::Node h = n["hysteresis"]; h.defined()) u.hysteresis = hysteresis(h);
    u.latch = n.optional("latch", false);
    for (const auto& d : u.depends_on) {
      if (d == u.name) n["depends_on"].error(fmt::format("'{}' depends on itself", u.name));
    }
    spec_.config.units.push_back(std::move(u));
  }

  void aggregate(const config::Node& n) {
    n.reject_unknown_keys({"name", "op", "k", "members", "depends_on", "hysteresis", "latch"});
    monitor::Aggregate a;
    a.name = name(n);
    a.op = n.optional_enum("op", monitor::AggregateOp::And, kOps);
    a.members = names(n.at("members"));
    if (n.has("members") && n["members"].is_sequence() && a.members.empty()) {
      n["members"].error("an aggregate needs at least one member");
    }
    if (a.op == monitor::AggregateOp::KOfN) {
      a.k = n.required<std::size_t>("k", config::positive());
      if (a.k > a.members.size() && !a.members.empty()) {
        n["k"].error(fmt::format("k = {} is more than its {} members", a.k, a.members.size()));
      }
    } else if (n.has("k")) {
      n["k"].error("k is for op: k_of_n");
    }
    a.depends_on = names(n["depends_on"]);
    if (const config::Node h = n["hysteresis"]; h.defined()) a.hysteresis = hysteresis(h);
    a.latch = n.optional("latch", false);
    spec_.config.aggregates.push_back(std::move(a));
  }

  DiagnosisSpec& spec_;
  std::map<std::string, int, std::less<>> names_;
};

}  // namespace

DiagnosisSpec parse_diagnosis(const config::Node& node) {
  DiagnosisSpec spec;
  Parser(spec).parse(node);
  return spec;
}

std::size_t check_unit_names(const DiagnosisSpec& spec, std::span<const std::string> known) {
  std::vector<std::string_view> all(known.begin(), known.end());
  for (const auto& a : spec.config.aggregates) all.push_back(a.name);
  std::size_t n = 0;
  for (const DiagnosisSpec::Reference& r : spec.references) {
    if (std::find(all.begin(), all.end(), r.name) != all.end()) continue;
    std::string msg = fmt::format("no unit named '{}'", r.name);
    if (const auto near = config::closest_match(r.name, std::span<const std::string_view>(all))) {
      msg += fmt::format("; did you mean '{}'?", *near);
    } else {
      msg +=
          " (units: components, \"supervision <name>\", CAN nodes \"can<bus>/<name>\" and "
          "groups \"can group <name>\", aggregates, vigil.supervisor, vigil.monitor)";
    }
    r.node.error(std::move(msg));
    ++n;
  }
  return n;
}

}  // namespace vigil::deploy
