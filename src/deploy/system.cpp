#include "vigil/deploy/system.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <exception>
#include <future>
#include <memory>
#include <span>
#include <thread>

#include "vigil/config/error.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/task/shm_messages.hpp"

namespace vigil::deploy {

System::System(DeploymentSpec spec) : spec_(std::move(spec)) {
  // The pipeline is a SupervisionService on the system's registry with the deployment's outputs
  // (added below, with access to the system); stop() ends with a last monitor cycle that the
  // outputs get, and reports() is that cycle's afterwards. The extensions are its contributors
  // (create()).
  const SupervisionSpec& sv = spec_.supervision;
  service::SupervisionServiceOptions o;
  o.registry = &registry_;
  o.supervisor_period_ns = sv.supervisor_period_ns;
  o.monitor_period_ns = sv.monitor_period_ns;
  o.final_cycle = true;  // the outputs get a last cycle after the last drain
  o.ewma_weight = sv.ewma_weight;
  o.summary_file = nullptr;
  o.monitor.stack_bytes = sv.monitor_stack_bytes;
  o.aggregator.warmup_ns = sv.warmup_ns;
  o.aggregator.watchdog = sv.watchdog;
  o.aggregator.recorder = sv.recorder;
  o.aggregator.events = {.queue_capacity = sv.event_queue};
  o.aggregator.auto_clear_ns = sv.auto_clear_ns;
  o.aggregator.state_events = sv.state_events;
  o.supervisor.stack_bytes = sv.supervisor_stack_bytes;
  const OutputSpec& out = spec_.outputs;
  if (out.http) {
    exporter::HttpOptions h;
    h.listen = out.http->listen;
    h.threads = out.http->threads;
    h.dashboard = out.http->dashboard;
    if (out.http->clear) {  // POST /api/v1/clear: off unless the deployment enables it
      h.clear = [this](const std::string& name) {
        // The aggregator's latched faults, and the diagnosis graph's latched units.
        const std::size_t n = name.empty() ? aggregator().clear_all() : aggregator().clear(name);
        return n + service_->clear_diagnosis(name);
      };
    }
    // The server logs at start only (its URL; a warning for a non-loopback address).
    h.log = [this](const std::string& line) { log_.push_back(line); };
    o.http = std::move(h);
  }
  service_ = std::make_unique<service::SupervisionService>(std::move(o));
  service_->monitor().set_thresholds(sv.thresholds);
  if (out.textfile) textfile_ = &service_->add_output<exporter::TextfileOutput>(*out.textfile);
  if (out.json) json_ = &service_->add_output<exporter::JsonFileOutput>(*out.json, 2);
  if (out.ros2) {
    ros2_ = &service_->add_output<exporter::Ros2DiagnosticsOutput>(
        exporter::Ros2Options{.domain_id = out.ros2->domain_id,
                              .dds_config = out.ros2->dds_config,
                              .events = out.ros2->events,
                              .node = out.ros2->node,
                              .node_name = out.ros2->node_name,
                              .node_namespace = out.ros2->node_namespace,
                              .ros_distro = out.ros2->ros_distro,
                              .warn = [](const std::string& line) {
                                std::fprintf(stderr, "outputs.ros2: %s\n", line.c_str());
                              }});
  }
}

System::~System() { stop(); }

expected<std::unique_ptr<System>, config::ConfigErrors> System::create(
    DeploymentSpec spec, const ComponentFactory& factory) {
  std::unique_ptr<System> sys(new System(std::move(spec)));
  const config::Node& root = sys->spec_.root;

  // Before any component joins: where their ports go (the deployment file, else the environment).
  if (const std::string& shm = sys->spec_.supervision.shared_memory; !shm.empty()) {
    bus::ShmOptions o;
    o.name = shm;
    if (auto r = place_in_shared_memory(sys->registry_, std::move(o)); !r) {
      root["supervision"]["shared_memory"].error(r.error().message);
    }
  } else {
    (void)bus::place_from_environment(sys->registry_, task::kShmMessageSchema,
                                      task::kShmStickyMessages);
  }

  if (sys->spec_.supervision.thresholds_file) {
    // The file was validated by the loader; it may have changed since, so load it again and
    // watch it: the monitor polls it at each cycle.
    auto file = ThresholdFile::open(*sys->spec_.supervision.thresholds_file);
    if (!file) return vigil::unexpected(file.error());
    sys->thresholds_file_.emplace(std::move(*file));
    sys->thresholds_file_->attach(sys->service_->monitor());
  }

  // Extensions first: components may use them (a CAN I/O component needs its sniffer).
  for (const ExtensionSection& section : sys->spec_.extensions) {
    const ExtensionMaker maker = find_extension(section.name);
    if (!maker) {
      section.node.error(
          fmt::format("no extension is registered for section '{}' in this program", section.name));
      continue;
    }
    auto ext = maker(section.node, *sys);
    if (!ext) return vigil::unexpected(ext.error());
    sys->service_->add_contributor(**ext);  // once per monitor cycle, on the monitor's thread
    sys->extensions_.push_back(std::move(*ext));
  }

  for (const ComponentSpec& c : sys->spec_.components) {
    const auto* type = factory.find(c.type);
    if (type == nullptr) continue;  // reported by parse_deployment
    ComponentContext ctx{c.name, c.supervision, c.parameters, &sys->registry_, sys.get()};
    Slot slot;
    slot.spec = &c;
    try {
      slot.task = type->make(ctx);
      if (!slot.task) c.node.error(fmt::format("component type '{}' made nothing", c.type));
    } catch (const std::exception& e) {
      c.node.error(
          fmt::format("component '{}' ({}) failed to build: {}", c.name, c.type, e.what()));
    }
    const ActivitySpec* act = nullptr;
    for (const auto& a : sys->spec_.activities) {
      if (a.config.name == c.activity) act = &a;
    }
    if (slot.task && act != nullptr) {
      slot.activity = std::make_unique<PeriodicActivity>(*slot.task, act->config);
    }
    sys->slots_.push_back(std::move(slot));
  }
  sys->supervise_health();
  sys->configure_diagnosis();
  sys->configure_reactions(factory);
  if (root.has_errors()) return vigil::unexpected(root.errors());
  return sys;
}

void System::supervise_health() {
  const HealthSpec& health = spec_.health;
  if (health.empty()) return;
  // Components that declare their checkpoints when built are checked now (so `vigil
  // check-config` finds a misspelt one); the others when they have configured (start()).
  for (Slot& s : slots_) {
    if (!s.task) continue;
    const std::vector<std::string> declared = s.task->declared_checkpoints();
    if (declared.empty()) {
      s.check_checkpoints_at_start = true;
    } else {
      (void)check_declared(health, s.spec->name, declared);
    }
  }
  // In shared memory, the components are supervised by `vigil supervise`, which reads this
  // section itself (`--health FILE`); this process has no checkpoint to see.
  if (registry_.shared_memory()) return;
  if (auto r = aggregator().supervise_health(health.config); !r) {
    spec_.root["health"].error(r.error().message);
  }
}

std::vector<std::string> System::known_units() const {
  std::vector<std::string> known{"vigil.supervisor", "vigil.monitor"};
  for (const ComponentSpec& c : spec_.components) known.push_back(c.name);
  for (const auto& a : spec_.health.config.alive) known.push_back("supervision " + a.name);
  for (const auto& a : spec_.health.config.deadline) known.push_back("supervision " + a.name);
  for (const auto& a : spec_.health.config.logical) known.push_back("supervision " + a.name);
  for (const auto& e : extensions_) {
    for (std::string& n : e->unit_names()) known.push_back(std::move(n));
  }
  if (!spec_.reactions.rules.empty()) known.emplace_back(service::Reactions::kUnitName);
  return known;
}

void System::configure_diagnosis() {
  const DiagnosisSpec& d = spec_.diagnosis;
  if (!d.defined) return;  // the default graph
  if (check_unit_names(d, known_units()) > 0 || spec_.root.has_errors()) return;
  if (auto r = service_->set_diagnosis(d.config); !r)
    spec_.root["diagnosis"].error(r.error().message);
}

void System::configure_reactions(const ComponentFactory& factory) {
  const ReactionsSpec& spec = spec_.reactions;
  if (!spec.defined) return;
  service::Reactions& reactions = service_->reactions();
  for (const ComponentFactory::Handler& h : factory.handlers()) {
    reactions.add_handler(h.name, h.fn, h.budget_ns);
  }
  reactions.set_dry_run(spec.dry_run);
  reactions.set_scheduling(spec.policy, spec.priority);
  std::vector<std::string> known = known_units();
  for (const auto& a : spec_.diagnosis.config.aggregates) known.push_back(a.name);
  const std::vector<std::string_view> units(known.begin(), known.end());
  for (std::size_t i = 0; i < spec.rules.size(); ++i) {
    const service::Reaction& r = spec.rules[i];
    const config::Node& n = spec.nodes[i];
    bool ok = true;
    auto unknown = [&](const config::Node& at, std::string what, std::string_view name,
                       std::span<const std::string_view> candidates) {
      std::string msg = fmt::format("no {} named '{}'", what, name);
      if (const auto near = config::closest_match(name, candidates)) {
        msg += fmt::format("; did you mean '{}'?", *near);
      }
      at.error(std::move(msg));
      ok = false;
    };
    if (!r.on.unit.empty() && std::find(known.begin(), known.end(), r.on.unit) == known.end()) {
      unknown(n["on"]["unit"], "unit", r.on.unit, units);
    }
    if (!r.on.component.empty() &&
        std::find(known.begin(), known.end(), r.on.component) == known.end()) {
      unknown(n["on"]["component"], "component or unit", r.on.component, units);
    }
    std::vector<std::string> handler_names;
    for (const auto& h : factory.handlers()) handler_names.push_back(h.name);
    const std::vector<std::string_view> hn(handler_names.begin(), handler_names.end());
    for (std::size_t k = 0; k < r.handlers.size(); ++k) {
      if (!reactions.has_handler(r.handlers[k])) {
        unknown(n["handlers"].elements()[k], "handler registered by this program", r.handlers[k],
                hn);
      }
    }
    for (std::size_t k = 0; k < r.can.size(); ++k) {
      if (!reactions.has_can_writer(r.can[k].writer)) {
        unknown(n["can"].elements()[k]["writer"], "CAN writer registered by this program",
                r.can[k].writer, {});
      }
    }
    if (!ok || spec_.root.has_errors()) continue;
    if (auto added = reactions.add(r); !added) n.error(added.error().message);
  }
}

expected<void, Error> System::start() {
  if (running_) return {};
  log_.clear();
  // Xenomai Cobalt: libcobalt starts before any thread of the system does, on the caller's thread
  // (the main thread; unless the program started it already). Linux: nothing to start.
  if (auto core = platform::initialize(); !core) return vigil::unexpected(core.error());
  // The malloc arenas are bounded before the pipeline starts its threads (glibc gives every
  // thread that allocates before the bound an arena of its own, for good); the rest of the
  // real-time set-up comes after it, so that a taken port fails before anything is locked (the
  // lock covers the pipeline's threads: MCL_CURRENT).
  const platform::RealtimeSetupOptions rt_options;
  if (spec_.supervision.lock_memory)
    (void)platform::bound_malloc_arenas(rt_options.malloc_arena_max);
  // The service starts its outputs first (a taken port fails here, before anything runs), then
  // the supervisor's thread and the monitor's.
  if (auto r = service_->start(); !r) {
    return vigil::unexpected(Error{
        r.error().code, spec_.outputs.http ? fmt::format("outputs.http: {}", r.error().message)
                                           : r.error().message});
  }
  if (ros2_ != nullptr && ros2_->active()) {
    const std::string node = ros2_->node();
    log_.push_back(fmt::format("ROS 2: /diagnostics (DDS topic rt/diagnostics) in domain {}{}",
                               ros2_->domain_id(), node.empty() ? "" : ", node " + node));
  }
  if (spec_.outputs.textfile) {
    log_.push_back(
        fmt::format("textfile {} rewritten every monitor cycle", spec_.outputs.textfile->string()));
  }
  if (spec_.supervision.lock_memory) {
    rt_setup_ = platform::setup_realtime_process(rt_options);
    log_.push_back(rt_setup_.memory_locked
                       ? fmt::format("memory locked; {} KiB of heap prefaulted; malloc arenas: {}",
                                     rt_setup_.heap_prefaulted / 1024,
                                     rt_setup_.malloc_arena_max > 0
                                         ? fmt::format("at most {}", rt_setup_.malloc_arena_max)
                                         : std::string("glibc default"))
                       : fmt::format("memory NOT locked (errno {}): page faults may hit the "
                                     "real-time threads",
                                     rt_setup_.lock_errno));
  }
  if (spec_.supervision.clock != platform::ClockSource::Monotonic ||
      platform::active_clock() != platform::ClockSource::Monotonic) {
    const platform::ClockSelection c = platform::select_clock(spec_.supervision.clock);
    log_.push_back(
        c.reason.empty()
            ? fmt::format("supervision clock: {} ({:.3f} GHz, re-calibrated every second)",
                          platform::to_string(c.active), c.tsc_ghz)
            : fmt::format("supervision clock: {}", c.reason));
  }
  log_.push_back(fmt::format("supervisor every {} ms, monitor every {} ms",
                             spec_.supervision.supervisor_period_ns / kNanosPerMilli,
                             spec_.supervision.monitor_period_ns / kNanosPerMilli));
  if (const auto shm = registry_.shared_memory()) {
    log_.push_back(
        fmt::format("components in shared memory: supervised by `vigil supervise "
                    "--name {}`, not by this process",
                    shm->session().options().name));
  }
  running_ = true;
  for (auto& e : extensions_) {
    if (auto r = e->start(); !r) {
      stop();
      return r;
    }
  }
  for (auto& s : slots_) {
    if (!s.task->configure()) {
      const auto state = s.task->state();
      stop();
      return vigil::unexpected(Error{fmt::format("component '{}' did not configure (state {})",
                                                 s.spec->name, to_string(state))});
    }
  }
  // Checkpoints named in `health:` that a component declares when it configures.
  std::vector<std::string> undeclared;
  for (const auto& s : slots_) {
    if (!s.check_checkpoints_at_start) continue;
    auto missing =
        undeclared_checkpoints(spec_.health, s.spec->name, s.task->declared_checkpoints());
    undeclared.insert(undeclared.end(), missing.begin(), missing.end());
  }
  if (!undeclared.empty()) {
    stop();
    return vigil::unexpected(Error{EINVAL, fmt::format("{}", fmt::join(undeclared, "\n"))});
  }
  if (!spec_.health.empty() && registry_.shared_memory()) {
    log_.push_back(fmt::format(
        "health: {} supervisions for `vigil supervise --name {} --health FILE`, not this process",
        spec_.health.config.alive.size() + spec_.health.config.deadline.size() +
            spec_.health.config.logical.size(),
        registry_.shared_memory()->session().options().name));
  }
  for (auto& s : slots_) {
    if (!s.activity) continue;
    if (auto r = s.activity->start(); !r) {
      if (s.spec->optional && r.error().code == ECANCELED) {  // it refused: run without it
        log_.push_back(fmt::format("{} refused to start (optional: the system runs without it)",
                                   s.spec->name));
        continue;
      }
      stop();
      return vigil::unexpected(Error{
          r.error().code, fmt::format("component '{}': {}", s.spec->name, r.error().message)});
    }
    const auto& info = s.activity->info();
    std::string line = fmt::format("{} on '{}': {} {} every {} us, thread {}", s.spec->name,
                                   info.name, platform::to_string(info.policy), info.priority,
                                   info.period_ns / kNanosPerMicro, info.tid);
    if (info.realtime_refused) line += " (SCHED_FIFO refused: running SCHED_OTHER, not real-time)";
    log_.push_back(std::move(line));
  }
  return {};
}

void System::stop() {
  if (!running_) return;
  for (auto& e : extensions_) e->stopping();
  for (auto it = slots_.rbegin(); it != slots_.rend(); ++it) {
    if (it->activity) it->activity->stop();
  }
  for (auto it = extensions_.rbegin(); it != extensions_.rend(); ++it) (*it)->stop();
  (void)service_->stop();  // the supervisor joins after a last drain, the monitor, the outputs
  running_ = false;
}

bool System::stop_within(Nanos timeout_ns) {
  auto done = std::make_shared<std::promise<void>>();
  std::future<void> stopped = done->get_future();
  std::thread([this, done] {
    stop();
    done->set_value();
  }).detach();
  return stopped.wait_for(std::chrono::nanoseconds(timeout_ns)) == std::future_status::ready;
}

ReportSet System::reports() const { return service_->reports(); }

ReportSet System::step_monitor() {
  return service_->step();  // drains first when the supervisor's thread does not run
}

std::string System::output_error() const {
  return textfile_ != nullptr ? textfile_->error() : std::string();
}

TaskCore* System::component(std::string_view name) const noexcept {
  for (const auto& s : slots_) {
    if (s.spec->name == name) return s.task.get();
  }
  return nullptr;
}

}  // namespace vigil::deploy
