#include "vigil/deploy/deployment.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <iterator>
#include <set>
#include <span>

#include "deploy/bytes.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/config/load.hpp"
#include "vigil/deploy/extension.hpp"
#include "vigil/export/ros2_diagnostics.hpp"

namespace vigil::deploy {

namespace {

using config::EnumName;

constexpr EnumName<SchedPolicy> kPolicies[] = {{"FIFO", SchedPolicy::Fifo},
                                               {"OTHER", SchedPolicy::Other}};
constexpr EnumName<OverrunPolicy> kOverrunPolicies[] = {{"skip", OverrunPolicy::Skip},
                                                        {"catch_up", OverrunPolicy::CatchUp},
                                                        {"reanchor", OverrunPolicy::Reanchor}};
constexpr EnumName<platform::ClockSource> kClocks[] = {
    {"monotonic", platform::ClockSource::Monotonic}, {"tsc", platform::ClockSource::Tsc}};
constexpr EnumName<supervisor::RingStores> kRingStores[] = {
    {"auto", supervisor::RingStores::Auto},
    {"cached", supervisor::RingStores::Cached},
    {"streaming", supervisor::RingStores::Streaming}};
constexpr EnumName<supervisor::RingPages> kRingPages[] = {
    {"auto", supervisor::RingPages::Auto},
    {"huge", supervisor::RingPages::Huge},
    {"ordinary", supervisor::RingPages::Ordinary}};
constexpr EnumName<Detectors> kDetectors[] = {{"allocation", Detectors::Allocation},
                                              {"blocking", Detectors::Blocking},
                                              {"page_faults", Detectors::PageFaults},
                                              {"mode_switch", Detectors::ModeSwitch},
                                              {"all", Detectors::All}};

ActivitySpec parse_activity(const config::Node& n) {
  n.reject_unknown_keys({"name", "period", "policy", "priority", "cpu", "overrun", "overrun_limit",
                         "share_thread", "fallback_to_other", "stack"});
  ActivitySpec a;
  PeriodicConfig& c = a.config;
  c.name = n.required<std::string>("name", config::non_empty());
  c.period_ns = n.required_period("period", config::positive());
  c.policy = n.optional_enum("policy", SchedPolicy::Other, kPolicies);
  if (c.policy == SchedPolicy::Fifo) {
    c.priority = n.required<int>("priority", config::in_range(1, 99));
  } else {
    c.priority = n.optional("priority", 0, config::in_range(0, 0));
  }
  c.cpu = n.optional("cpu", -1, config::in_range(-1, 1023));
  c.overrun_policy = n.optional_enum("overrun", OverrunPolicy::Skip, kOverrunPolicies);
  if (const config::Node lim = n["overrun_limit"]; lim.defined()) {
    lim.reject_unknown_keys({"overruns", "window"});
    c.overrun_limit.max_overruns = lim.required<std::uint32_t>("overruns", config::positive());
    c.overrun_limit.window_cycles = lim.required<std::uint32_t>("window", config::positive());
    if (c.overrun_limit.max_overruns > c.overrun_limit.window_cycles) {
      lim.error("overruns must not exceed window (cycles)");
    }
  }
  c.share_thread = n.optional("share_thread", true);
  c.fallback_to_other = n.optional("fallback_to_other", true);
  c.stack_bytes = detail::optional_stack(n, "stack", kDefaultActivityStackBytes);
  return a;
}

ComponentSpec parse_component(const config::Node& n, const ComponentFactory& factory) {
  n.reject_unknown_keys({"name", "type", "activity", "detectors", "overhead_sample_every",
                         "optional", "safe_state", "parameters"});
  ComponentSpec c;
  c.node = n;
  c.name = n.required<std::string>("name", config::non_empty());
  c.type = n.required<std::string>("type", config::non_empty());
  c.activity = n.required<std::string>("activity", config::non_empty());
  if (const config::Node t = n["type"]; t.defined() && !c.type.empty() && !factory.find(c.type)) {
    const auto types = factory.types();
    std::vector<std::string_view> names;
    names.reserve(types.size());
    for (const auto& type : types) names.push_back(type.name);
    std::string msg = fmt::format("unknown component type '{}'", c.type);
    if (const auto near = config::closest_match(c.type, std::span<const std::string_view>(names))) {
      msg += fmt::format("; did you mean '{}'?", *near);
    } else if (!names.empty()) {
      msg += fmt::format(" (known: {})", fmt::join(names, ", "));
    }
    t.error(msg);
  }
  Detectors d = Detectors::None;
  if (const config::Node det = n["detectors"]; det.defined()) {
    if (!det.is_sequence()) {
      det.error(
          "expected a list of detectors (allocation, blocking, page_faults, mode_switch, "
          "all)");
    } else {
      for (const auto& e : det.elements()) d = d | e.get_enum(kDetectors);
    }
  }
  c.supervision.detectors = d;
  // Any count: the recorder counts cycles down (0: never).
  c.supervision.overhead_sample_every = n.optional<std::uint32_t>("overhead_sample_every", 64);
  c.optional = n.optional("optional", false);
  // What the component does while the safe state is requested (vigil/safe_state.hpp): run its
  // own fallback or on_update() (`run`), or stop (`stop`).
  static constexpr config::EnumName<bool> kSafeState[] = {{"run", false}, {"stop", true}};
  c.supervision.stop_on_safe_state = n.optional_enum("safe_state", false, kSafeState);
  c.parameters = n["parameters"];
  if (c.parameters.defined() && !c.parameters.is_mapping() && !c.parameters.is_null()) {
    c.parameters.error("expected a mapping of parameters");
  }
  return c;
}

// Top-level keys: the built-in ones, then the sections of registered extensions (kept in `d`).
void parse_sections(const config::Node& root, DeploymentSpec& d) {
  constexpr std::string_view kBuiltIn[] = {"name",    "activities", "components", "supervision",
                                           "outputs", "health",     "diagnosis",  "reactions"};
  const std::vector<std::string> registered = registered_extensions();
  std::vector<std::string_view> allowed(std::begin(kBuiltIn), std::end(kBuiltIn));
  allowed.insert(allowed.end(), registered.begin(), registered.end());
  for (const auto& [key, value] : root.entries()) {
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) {
      if (std::find(std::begin(kBuiltIn), std::end(kBuiltIn), key) == std::end(kBuiltIn)) {
        d.extensions.push_back({key, value});
      }
      continue;
    }
    if (const auto near = config::closest_match(key, std::span<const std::string_view>(allowed))) {
      value.error(fmt::format("unknown key '{}'; did you mean '{}'?", key, *near));
    } else {
      value.error(fmt::format(
          "unknown section '{}': not a deployment key ({}) and no extension handles it in this "
          "program (registered: {}); link the library that provides it (e.g. vigil::deploy_can)",
          key, fmt::join(kBuiltIn, ", "),
          registered.empty() ? std::string("none")
                             : fmt::format("{}", fmt::join(registered, ", "))));
    }
  }
}

using Names = std::set<std::string, std::less<>>;

// `activities`; returns their names.
Names parse_activities(const config::Node& root, DeploymentSpec& d) {
  Names names;
  const config::Node acts = root.at("activities");
  if (acts.defined() && !acts.is_sequence()) acts.error("expected a list of activities");
  for (const auto& n : acts.elements()) {
    ActivitySpec a = parse_activity(n);
    if (!a.config.name.empty() && !names.insert(a.config.name).second) {
      n["name"].error(fmt::format("activity '{}' is defined twice", a.config.name));
    }
    d.activities.push_back(std::move(a));
  }
  return names;
}

// `components`, each on one of `activities`.
void parse_components(const config::Node& root, const ComponentFactory& factory,
                      const Names& activities, DeploymentSpec& d) {
  Names names;
  const config::Node comps = root.at("components");
  if (comps.defined() && !comps.is_sequence()) comps.error("expected a list of components");
  for (const auto& n : comps.elements()) {
    ComponentSpec c = parse_component(n, factory);
    if (!c.name.empty() && !names.insert(c.name).second) {
      n["name"].error(fmt::format("component '{}' is defined twice", c.name));
    }
    if (!c.activity.empty() && !activities.contains(c.activity)) {
      n["activity"].error(fmt::format("no activity named '{}' (defined: {})", c.activity,
                                      fmt::join(activities, ", ")));
    }
    d.components.push_back(std::move(c));
  }
  if (comps.defined() && comps.is_sequence() && d.components.empty()) {
    comps.error("a deployment needs at least one component");
  }
}

// `supervision.watchdog`.
void parse_watchdog(const config::Node& w, supervisor::WatchdogOptions& wd) {
  w.reject_unknown_keys({"enabled", "periods", "floor", "aperiodic"});
  wd.enabled = w.optional("enabled", wd.enabled);
  wd.periods = w.optional("periods", wd.periods, config::in_range(1.0, 1e6));
  wd.floor_ns = w.optional_duration("floor", wd.floor_ns,
                                    config::duration_in_range(0, 3600 * kNanosPerSecond));
  wd.aperiodic_ns = w.optional_duration("aperiodic", wd.aperiodic_ns,
                                        config::duration_in_range(0, 3600 * kNanosPerSecond));
}

// `supervision.events`.
void parse_events(const config::Node& e, SupervisionSpec& sp) {
  e.reject_unknown_keys({"queue", "auto_clear", "state_changes"});
  sp.event_queue =
      e.optional<std::size_t>("queue", sp.event_queue, config::in_range<std::size_t>(1, 1U << 20U));
  sp.auto_clear_ns = e.optional_duration("auto_clear", sp.auto_clear_ns,
                                         config::duration_in_range(0, 86400 * kNanosPerSecond));
  sp.state_events = e.optional("state_changes", sp.state_events);
}

// `supervision.flight_recorder`.
void parse_flight_recorder(const config::Node& f, supervisor::FlightRecorderOptions& r) {
  f.reject_unknown_keys({"cycles", "min_interval", "max_records", "stores", "pages"});
  r.cycles =
      f.optional<std::size_t>("cycles", r.cycles, config::in_range<std::size_t>(0, 1U << 20U));
  r.min_interval_ns = f.optional_duration("min_interval", r.min_interval_ns,
                                          config::duration_in_range(0, 86400 * kNanosPerSecond));
  r.max_records = f.optional<std::size_t>("max_records", r.max_records,
                                          config::in_range<std::size_t>(0, 1U << 20U));
  r.stores = f.optional_enum("stores", r.stores, kRingStores);
  r.pages = f.optional_enum("pages", r.pages, kRingPages);
}

// `supervision.thresholds`: a file (relative to the deployment's) or the thresholds themselves.
void parse_thresholds(const config::Node& t, const config::Node& root, SupervisionSpec& sp) {
  if (!t.is_scalar()) {
    auto loaded = load_thresholds(t);
    if (loaded) sp.thresholds = std::move(*loaded);
    return;
  }
  std::filesystem::path p = t.get<std::string>();
  if (p.is_relative() && !root.file().empty()) {
    p = std::filesystem::path(root.file()).parent_path() / p;
  }
  auto loaded = load_thresholds_file(p);
  if (!loaded) {
    t.error(fmt::format("thresholds file '{}' is invalid:\n{}", p.string(),
                        config::to_string(loaded.error())));
  } else {
    sp.thresholds = std::move(*loaded);
    sp.thresholds_file = p;
  }
}

// `supervision`.
void parse_supervision(const config::Node& s, const config::Node& root, SupervisionSpec& sp) {
  s.reject_unknown_keys({"supervisor_period", "monitor_period", "ewma_weight", "thresholds",
                         "lock_memory", "supervisor_stack", "monitor_stack", "shared_memory",
                         "warmup", "watchdog", "events", "flight_recorder", "clock"});
  sp.supervisor_period_ns =
      s.optional_period("supervisor_period", sp.supervisor_period_ns,
                        config::duration_in_range(100 * kNanosPerMicro, 10 * kNanosPerSecond));
  sp.monitor_period_ns =
      s.optional_period("monitor_period", sp.monitor_period_ns,
                        config::duration_in_range(kNanosPerMilli, 3600 * kNanosPerSecond));
  sp.ewma_weight = s.optional("ewma_weight", sp.ewma_weight, config::in_range(1e-6, 1.0));
  sp.lock_memory = s.optional("lock_memory", true);
  sp.clock = s.optional_enum("clock", sp.clock, kClocks);
  sp.supervisor_stack_bytes =
      detail::optional_stack(s, "supervisor_stack", sp.supervisor_stack_bytes);
  sp.monitor_stack_bytes = detail::optional_stack(s, "monitor_stack", sp.monitor_stack_bytes);
  sp.shared_memory = s.optional<std::string>("shared_memory", "");
  sp.warmup_ns = s.optional_duration("warmup", sp.warmup_ns,
                                     config::duration_in_range(0, 3600 * kNanosPerSecond));
  if (const config::Node w = s["watchdog"]; w.defined()) parse_watchdog(w, sp.watchdog);
  if (const config::Node e = s["events"]; e.defined()) parse_events(e, sp);
  if (const config::Node f = s["flight_recorder"]; f.defined()) {
    parse_flight_recorder(f, sp.recorder);
  }
  if (const config::Node m = s["shared_memory"];
      m.defined() && !bus::valid_supervisor_name(sp.shared_memory)) {
    m.error(
        fmt::format("'{}' is not a supervisor name: 1 to 31 of A-Z a-z 0-9 _ -", sp.shared_memory));
  }
  if (const config::Node t = s["thresholds"]; t.defined()) parse_thresholds(t, root, sp);
}

// `outputs.http`.
HttpOutputSpec parse_http(const config::Node& h) {
  h.reject_unknown_keys({"listen", "threads", "dashboard", "clear"});
  HttpOutputSpec http;
  const auto listen_check = [](const std::string& v) -> std::optional<std::string> {
    auto a = exporter::parse_listen(v);
    if (!a) return a.error();
    return std::nullopt;
  };
  const std::string listen = h.required<std::string>("listen", listen_check);
  if (auto a = exporter::parse_listen(listen)) http.listen = *a;
  http.threads = h.optional("threads", 3U, config::in_range(1U, 16U));
  http.dashboard = h.optional("dashboard", true);
  http.clear = h.optional("clear", false);
  return http;
}

// `outputs.ros2`.
Ros2OutputSpec parse_ros2(const config::Node& r) {
  Ros2OutputSpec ros2;
  if (r.is_null()) return ros2;  // `ros2:` alone: every default
  r.reject_unknown_keys(
      {"domain_id", "dds_config", "events", "node", "node_name", "node_namespace", "ros_distro"});
  if (r.has("domain_id")) {
    ros2.domain_id = r.required<int>("domain_id", config::in_range(0, exporter::kRosDomainIdMax));
  }
  ros2.dds_config = r.optional<std::string>("dds_config", "", config::non_empty());
  ros2.events = r.optional("events", true);
  ros2.node = r.optional("node", true);
  // Each check's error starts with the key and the value ("node_name 'a b' is not a ROS 2 node
  // name: it ..."); the loader names both, so the rest is said as a requirement ("must be a ...").
  const auto said = [](const Error& e) {
    const std::size_t at = e.message.find("' is not ");
    return at == std::string::npos ? e.message : "must be " + e.message.substr(at + 9);
  };
  ros2.node_name = r.optional<std::string>("node_name", "vigil",
                                           [&](const std::string& v) -> std::optional<std::string> {
                                             if (auto c = exporter::check_ros_node_name(v); !c)
                                               return said(c.error());
                                             return std::nullopt;
                                           });
  ros2.node_namespace = r.optional<std::string>(
      "node_namespace", "/", [&](const std::string& v) -> std::optional<std::string> {
        if (auto c = exporter::check_ros_namespace(v); !c) return said(c.error());
        return std::nullopt;
      });
  ros2.ros_distro = r.optional<std::string>(
      "ros_distro", "", [](const std::string& v) -> std::optional<std::string> {
        if (auto g = exporter::ros_gid_size(v); !g) {
          return "must name a ROS 2 distribution: foxy, galactic, humble, iron, jazzy, kilted, "
                 "lyrical or rolling";
        }
        return std::nullopt;
      });
  return ros2;
}

// `outputs`.
void parse_outputs(const config::Node& o, OutputSpec& out) {
  o.reject_unknown_keys({"json", "http", "textfile", "ros2"});
  if (o.has("json")) out.json = o.required<std::string>("json", config::non_empty());
  if (o.has("textfile")) {
    out.textfile = o.required<std::string>("textfile", config::non_empty());
  }
  if (const config::Node h = o["http"]; h.defined()) out.http = parse_http(h);
  if (const config::Node r = o["ros2"]; r.defined()) out.ros2 = parse_ros2(r);
}

}  // namespace

expected<DeploymentSpec, config::ConfigErrors> parse_deployment(const config::Node& root,
                                                                const ComponentFactory& factory) {
  DeploymentSpec d;
  d.root = root;
  if (!root.is_mapping()) {
    root.error(
        "a deployment is a mapping with activities, components, supervision, outputs, health, "
        "diagnosis, reactions");
    return root.finish(std::move(d));
  }
  parse_sections(root, d);
  d.name = root.optional<std::string>("name", "vigil", config::non_empty());
  const Names activities = parse_activities(root, d);
  parse_components(root, factory, activities, d);
  if (const config::Node s = root["supervision"]; s.defined()) {
    parse_supervision(s, root, d.supervision);
  }
  if (const config::Node o = root["outputs"]; o.defined()) parse_outputs(o, d.outputs);
  if (const config::Node h = root["health"]; h.defined()) {
    std::vector<std::string> names;
    names.reserve(d.components.size());
    for (const ComponentSpec& c : d.components) names.push_back(c.name);
    d.health = parse_health(h, names);
  }
  if (const config::Node g = root["diagnosis"]; g.defined()) d.diagnosis = parse_diagnosis(g);
  if (const config::Node r = root["reactions"]; r.defined()) d.reactions = parse_reactions(r);
  return root.finish(std::move(d));
}

expected<DeploymentSpec, config::ConfigErrors> load_deployment_file(
    const std::filesystem::path& path, const ComponentFactory& factory) {
  auto root = config::load_file(path);
  if (!root) return vigil::unexpected(root.error());
  return parse_deployment(*root, factory);
}

expected<DeploymentSpec, config::ConfigErrors> load_deployment_string(
    std::string_view text, std::string name, const ComponentFactory& factory) {
  auto root = config::load_string(text, std::move(name));
  if (!root) return vigil::unexpected(root.error());
  return parse_deployment(*root, factory);
}

}  // namespace vigil::deploy
