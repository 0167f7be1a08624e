#include "vigil/monitor/diagnosis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <functional>
#include <set>
#include <stdexcept>
#include <utility>

namespace vigil::monitor {

const char* to_string(AggregateOp op) noexcept {
  switch (op) {
    case AggregateOp::And:
      return "and";
    case AggregateOp::Or:
      return "or";
    case AggregateOp::KOfN:
      return "k_of_n";
  }
  return "?";
}

namespace {

using Edges = std::map<std::string, std::vector<std::string>, std::less<>>;

// The configured edges: units' depends_on, aggregates' members and depends_on.
Edges configured_edges(const DiagnosisConfig& c) {
  Edges e;
  for (const auto& u : c.units) {
    auto& to = e[u.name];
    to.insert(to.end(), u.depends_on.begin(), u.depends_on.end());
  }
  for (const auto& a : c.aggregates) {
    auto& to = e[a.name];
    to.insert(to.end(), a.members.begin(), a.members.end());
    to.insert(to.end(), a.depends_on.begin(), a.depends_on.end());
  }
  return e;
}

// A cycle among `edges`, as "a -> b -> a"; empty when there is none.
std::string find_cycle(const Edges& edges) {
  std::map<std::string, int, std::less<>> color;  // 0 new, 1 on the path, 2 done
  std::vector<std::string> path;
  std::string found;
  std::function<bool(const std::string&)> visit = [&](const std::string& n) {
    color[n] = 1;
    path.push_back(n);
    if (const auto it = edges.find(n); it != edges.end()) {
      for (const auto& m : it->second) {
        const int c = color[m];
        if (c == 1) {
          const auto start = std::find(path.begin(), path.end(), m);
          for (auto p = start; p != path.end(); ++p) found += *p + " -> ";
          found += m;
          return true;
        }
        if (c == 0 && visit(m)) return true;
      }
    }
    path.pop_back();
    color[n] = 2;
    return false;
  };
  for (const auto& [n, to] : edges) {
    if (color[n] == 0 && visit(n)) return found;
  }
  return {};
}

// Levels from best to worst: OK, WARN, ERROR, STALE.
int rank(StatusLevel l) noexcept { return static_cast<int>(l); }

std::string ns(Nanos v) { return format_nanos(static_cast<double>(v)); }

}  // namespace

expected<void, Error> validate(const DiagnosisConfig& c) {
  const auto bad = [](std::string m) { return vigil::unexpected(Error{EINVAL, std::move(m)}); };
  std::set<std::string, std::less<>> names;
  for (const auto& u : c.units) {
    if (u.name.empty()) return bad("a diagnosis unit has no name");
    if (!names.insert(u.name).second) return bad(fmt::format("unit '{}' is named twice", u.name));
    for (const auto& d : u.depends_on) {
      if (d == u.name) return bad(fmt::format("unit '{}' depends on itself", u.name));
    }
  }
  for (const auto& a : c.aggregates) {
    if (a.name.empty()) return bad("an aggregate has no name");
    if (!names.insert(a.name).second) {
      return bad(fmt::format("aggregate '{}': the name is taken", a.name));
    }
    if (a.members.empty()) return bad(fmt::format("aggregate '{}' has no members", a.name));
    if (a.op == AggregateOp::KOfN && (a.k < 1 || a.k > a.members.size())) {
      return bad(fmt::format("aggregate '{}': k = {} is not within 1..{} (its members)", a.name,
                             a.k, a.members.size()));
    }
    for (const auto& m : a.members) {
      if (m == a.name) return bad(fmt::format("aggregate '{}' is its own member", a.name));
    }
  }
  if (c.hysteresis.raise_after_ns < 0 || c.hysteresis.clear_after_ns < 0 || c.startup_ns < 0) {
    return bad("a negative duration");
  }
  if (std::string cycle = find_cycle(configured_edges(c)); !cycle.empty()) {
    return bad(fmt::format("the dependencies form a cycle: {}", cycle));
  }
  return {};
}

DiagnosisGraph::DiagnosisGraph(DiagnosisConfig config) : config_(std::move(config)) {
  if (auto ok = validate(config_); !ok) throw std::invalid_argument(ok.error().message);
  for (const auto& u : config_.units) units_.emplace(u.name, &u);
}

void DiagnosisGraph::filter(Report& r, const Hysteresis& h, bool latch, Nanos now) {
  UnitState& st = state_[r.name];
  const StatusLevel raw = r.status.level();
  if (raw != StatusLevel::Ok) st.last_messages = r.status.messages();
  if (raw == st.shown) {
    st.pending = raw;
    st.pending_since = now;
    st.pending_cycles = 1;
  } else {
    if (raw != st.pending) {
      st.pending = raw;
      st.pending_since = now;
      st.pending_cycles = 0;
    }
    ++st.pending_cycles;
    const bool raising = rank(raw) > rank(st.shown);
    const Nanos need = raising ? h.raise_after_ns : h.clear_after_ns;
    const std::uint32_t need_cycles = raising ? h.raise_after_cycles : h.clear_after_cycles;
    if (now - st.pending_since >= need && st.pending_cycles >= need_cycles) st.shown = raw;
  }
  if (latch && st.shown == StatusLevel::Error && !st.latched) {
    st.latched = true;
    st.latched_messages = r.status.messages();
  }
  StatusLevel shown = st.shown;
  if (st.latched && rank(shown) < rank(StatusLevel::Error)) shown = StatusLevel::Error;
  if (shown == raw) return;
  Status s;
  if (st.latched && shown == StatusLevel::Error && st.shown != StatusLevel::Error) {
    s.merge(StatusLevel::Error, fmt::format("latched (now {}; clear to reset)", to_string(raw)));
    for (const auto& m : st.latched_messages) s.merge(StatusLevel::Ok, m.text);
  } else if (rank(shown) < rank(raw)) {
    // Raised, but not for long enough yet: the shown status holds, the new one is said.
    s.merge(shown);
    s.merge(StatusLevel::Ok,
            h.raise_after_cycles > 0
                ? fmt::format("{} for {} and {} cycles (shown after {} and {} cycles)",
                              to_string(raw), ns(now - st.pending_since), st.pending_cycles,
                              ns(h.raise_after_ns), h.raise_after_cycles)
                : fmt::format("{} for {} (shown after {})", to_string(raw),
                              ns(now - st.pending_since), ns(h.raise_after_ns)));
    for (const auto& m : r.status.messages()) s.merge(StatusLevel::Ok, m.text);
  } else {
    // Better, but not for long enough yet: the worse status holds, with its last reasons.
    s.merge(shown, h.clear_after_cycles > 0
                       ? fmt::format("clearing: {} for {} and {} cycles (cleared after {} and {} "
                                     "cycles)",
                                     to_string(raw), ns(now - st.pending_since), st.pending_cycles,
                                     ns(h.clear_after_ns), h.clear_after_cycles)
                       : fmt::format("clearing: {} for {} (cleared after {})", to_string(raw),
                                     ns(now - st.pending_since), ns(h.clear_after_ns)));
    for (const auto& m : st.last_messages) {
      s.merge(rank(m.level) > rank(shown) ? shown : m.level, m.text);
    }
  }
  r.status = std::move(s);
}

Report DiagnosisGraph::aggregate(const Aggregate& a, const ReportSet& reports) const {
  Report r;
  r.kind = ReportKind::Unit;
  r.unit_kind = std::string(kAggregateUnit);
  r.name = a.name;
  std::vector<StatusLevel> levels;
  std::vector<std::string> failing;
  std::uint64_t ok = 0;
  for (const auto& m : a.members) {
    const Report* mr = reports.find(m);
    const StatusLevel l = mr != nullptr ? mr->status.level() : StatusLevel::Stale;
    levels.push_back(l);
    if (l == StatusLevel::Ok) {
      ++ok;
    } else {
      failing.push_back(mr != nullptr ? fmt::format("{} {}", m, to_string(l))
                                      : fmt::format("{} absent", m));
    }
  }
  std::sort(levels.begin(), levels.end(), [](auto x, auto y) { return rank(x) < rank(y); });
  const std::size_t k = a.op == AggregateOp::And  ? a.members.size()
                        : a.op == AggregateOp::Or ? 1
                                                  : a.k;
  const StatusLevel level = levels[k - 1];
  if (level != StatusLevel::Ok) {
    r.status.merge(level, fmt::format("{} of {} members OK (needs {}): {}", ok, a.members.size(), k,
                                      fmt::join(failing, ", ")));
  }
  r.state_label =
      level == StatusLevel::Ok ? (failing.empty() ? "all ok" : "ok, degraded") : "failed";
  r.add_field(Field::of_text("op", to_string(a.op)));
  r.add_field(Field::of_count("members", a.members.size()));
  r.add_field(Field::of_count("ok", ok));
  r.add_field(Field::of_count("needed", k));
  r.depends_on = a.members;
  r.depends_on.insert(r.depends_on.end(), a.depends_on.begin(), a.depends_on.end());
  return r;
}

void DiagnosisGraph::apply(ReportSet& reports, Nanos now) {
  if (first_ < 0) first_ = now;
  // 1. Hysteresis and latches of the reports, then the aggregates built on what they show.
  for (Report& r : reports.components) {
    const auto it = units_.find(r.name);
    const DiagnosisUnit* u = it != units_.end() ? it->second : nullptr;
    const Hysteresis& h = u != nullptr && u->hysteresis ? *u->hysteresis : config_.hysteresis;
    filter(r, h, u != nullptr && u->latch, now);
    if (!config_.contributor_edges) r.depends_on.clear();
    if (u != nullptr)
      r.depends_on.insert(r.depends_on.end(), u->depends_on.begin(), u->depends_on.end());
  }
  for (const Aggregate& a : config_.aggregates) {
    Report r = aggregate(a, reports);
    filter(r, a.hysteresis ? *a.hysteresis : config_.hysteresis, a.latch, now);
    reports.components.push_back(std::move(r));
  }
  // 2. Start-up suppression: shown OK, the reasons kept.
  if (config_.startup_ns > 0 && now - first_ < config_.startup_ns) {
    for (Report& r : reports.components) {
      if (r.status.ok()) continue;
      Status s(StatusLevel::Ok, fmt::format("start-up ({} of {}): {} suppressed", ns(now - first_),
                                            ns(config_.startup_ns), to_string(r.status.level())));
      for (const auto& m : r.status.messages()) s.merge(StatusLevel::Ok, m.text);
      r.status = std::move(s);
    }
  }
  // 3. Root causes: a report not OK whose failed dependencies explain it names their roots.
  std::map<std::string_view, std::size_t, std::less<>> index;
  for (std::size_t i = 0; i < reports.components.size(); ++i) {
    index.emplace(reports.components[i].name, i);
  }
  const auto failing = [&](const std::string& name) -> const Report* {
    const auto it = index.find(name);
    if (it == index.end()) return nullptr;
    const Report& d = reports.components[it->second];
    return d.status.ok() ? nullptr : &d;
  };
  std::map<std::string_view, std::vector<std::string>, std::less<>> memo;
  std::set<std::string_view, std::less<>> visiting;
  std::function<const std::vector<std::string>&(const Report&)> roots =
      [&](const Report& r) -> const std::vector<std::string>& {
    if (const auto it = memo.find(r.name); it != memo.end()) return it->second;
    std::vector<std::string> out;
    visiting.insert(r.name);
    for (const auto& d : r.depends_on) {
      const Report* dr = failing(d);
      if (dr == nullptr || visiting.contains(dr->name)) continue;  // OK, absent, or a loop
      for (const auto& root : roots(*dr)) {
        if (std::find(out.begin(), out.end(), root) == out.end()) out.push_back(root);
      }
    }
    visiting.erase(r.name);
    if (out.empty()) out.push_back(r.name);  // nothing failed below it: it is a root
    return memo.emplace(r.name, std::move(out)).first->second;
  };
  reports.root_causes.clear();
  for (Report& r : reports.components) {
    r.caused_by.clear();
    if (r.status.ok()) continue;
    const std::vector<std::string>& rs = roots(r);
    if (rs.size() == 1 && rs.front() == r.name) {
      reports.root_causes.push_back(r.name);
    } else {
      r.caused_by = rs;
    }
  }
}

std::size_t DiagnosisGraph::clear(std::string_view name) {
  std::size_t n = 0;
  for (auto& [unit, st] : state_) {
    if (!name.empty() && unit != name) continue;
    if (!st.latched) continue;
    st.latched = false;
    st.latched_messages.clear();
    ++n;
  }
  return n;
}

}  // namespace vigil::monitor
