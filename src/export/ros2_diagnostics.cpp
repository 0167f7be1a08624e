#include "vigil/export/ros2_diagnostics.hpp"

#include <dlfcn.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>

#include "ros2_transport.hpp"
#include "vigil/version.hpp"

namespace vigil::exporter {

namespace {

// --- the module (as the HTTP server's, http_server.cpp) ---------------------------------------

// Opened once per process and never closed: a transport's code must stay mapped while any
// transport lives.
std::mutex module_mutex;
VigilRos2TransportCreateFn module_create = nullptr;  // guarded by module_mutex

expected<VigilRos2TransportCreateFn, std::string> open_module(const std::string& path) {
  void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = ::dlerror();
    return vigil::unexpected(why != nullptr ? std::string(why) : path + ": cannot be opened");
  }
  const auto abi =
      reinterpret_cast<VigilRos2TransportAbiFn>(::dlsym(handle, detail::kRos2ModuleAbiSymbol));
  const auto version = reinterpret_cast<VigilRos2TransportVersionFn>(
      ::dlsym(handle, detail::kRos2ModuleVersionSymbol));
  const auto create = reinterpret_cast<VigilRos2TransportCreateFn>(
      ::dlsym(handle, detail::kRos2ModuleCreateSymbol));
  std::string wrong;
  if (abi == nullptr || version == nullptr || create == nullptr) {
    wrong =
        fmt::format("{}: not a vigil ROS 2 module (no {})", path, detail::kRos2ModuleCreateSymbol);
  } else if (abi() != detail::kRos2TransportAbi || std::strcmp(version(), kVersion) != 0) {
    wrong = fmt::format(
        "{}: built from vigil {} (interface {}), this program is vigil {} "
        "(interface {})",
        path, version(), abi(), kVersion, detail::kRos2TransportAbi);
  }
  if (!wrong.empty()) {
    (void)::dlclose(handle);
    return vigil::unexpected(std::move(wrong));
  }
  return create;
}

// Where the module is looked for, in order (docs/reference/environment.md, VIGIL_ROS2_MODULE).
std::vector<std::string> module_candidates() {
  if (const char* env = std::getenv("VIGIL_ROS2_MODULE"); env != nullptr && *env != '\0') {
    return {env};  // an explicit choice: nothing else is tried
  }
  std::vector<std::string> c;
  c.emplace_back(detail::kRos2ModuleFile);  // RUNPATH, LD_LIBRARY_PATH, the system's
#ifdef VIGIL_ROS2_MODULE_BUILD_PATH
  if (::access(VIGIL_ROS2_MODULE_BUILD_PATH, F_OK) == 0) {
    c.emplace_back(VIGIL_ROS2_MODULE_BUILD_PATH);  // this build tree's
  }
#endif
#ifdef VIGIL_ROS2_MODULE_INSTALL_PATH
  c.emplace_back(VIGIL_ROS2_MODULE_INSTALL_PATH);
#endif
  return c;
}

expected<VigilRos2TransportCreateFn, std::string> load_module() {
  std::lock_guard lock(module_mutex);
  if (module_create != nullptr) return module_create;
  if (!ros2_output_built() && std::getenv("VIGIL_ROS2_MODULE") == nullptr) {
    return vigil::unexpected(std::string(
        "this vigil was built without Cyclone DDS (Debian cyclonedds-dev, found at configure "
        "time): no ROS 2 /diagnostics"));
  }
  std::string tried;
  for (const std::string& path : module_candidates()) {
    auto m = open_module(path);
    if (m) {
      module_create = *m;
      return *m;
    }
    tried += "\n  " + m.error();
  }
  return vigil::unexpected(
      fmt::format("cannot load the ROS 2 module {} (set VIGIL_ROS2_MODULE to its path):{}",
                  detail::kRos2ModuleFile, tried));
}

std::uint8_t event_level(EventSeverity s) {
  switch (s) {
    case EventSeverity::Info:
      return 0;
    case EventSeverity::Warn:
      return 1;
    case EventSeverity::Error:
      return 2;
  }
  return 0;
}

}  // namespace

bool ros2_output_built() noexcept {
#ifdef VIGIL_ROS2_MODULE_BUILD_PATH
  return true;
#else
  return false;
#endif
}

expected<int, Error> parse_ros_domain_id(std::string_view text, std::string_view what) {
  int v = -1;
  const char* end = text.data() + text.size();
  const auto [p, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc{} || p != end || v < 0 || v > kRosDomainIdMax) {
    return vigil::unexpected(
        Error(EINVAL, fmt::format("{}='{}' is not a DDS domain id: an integer from 0 to {} (ROS 2 "
                                  "advises 0 to 101 on Linux)",
                                  what, text.substr(0, 40), kRosDomainIdMax)));
  }
  return v;
}

expected<int, Error> ros_gid_size(std::string_view distro, std::string_view what) {
  // rmw_dds_common/msg/Gid.msg: `char[24] data` up to Humble (1.6.x), `char[16] data` since Iron
  // (2.0.0, "Change Gid.msg to be 16 bytes", ros2/rmw_dds_common#68).
  for (const std::string_view d : {"foxy", "galactic", "humble"}) {
    if (distro == d) return 24;
  }
  for (const std::string_view d : {"iron", "jazzy", "kilted", "lyrical", "rolling"}) {
    if (distro == d) return 16;
  }
  return vigil::unexpected(
      Error(EINVAL,
            fmt::format("{}='{}' is not a ROS 2 distribution vigil knows (foxy, galactic, humble: "
                        "24-byte graph ids; iron, jazzy, kilted, lyrical, rolling: 16)",
                        what, distro.substr(0, 40))));
}

namespace {
bool ros_name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
}
bool ros_digit(char c) { return c >= '0' && c <= '9'; }
}  // namespace

expected<void, Error> check_ros_node_name(std::string_view name) {
  const char* why = nullptr;
  if (name.empty()) {
    why = "is empty";
  } else if (name.size() > 255) {
    why = "is longer than 255 characters";
  } else if (!std::all_of(name.begin(), name.end(), ros_name_char)) {
    why = "may hold only letters, digits and '_'";
  } else if (ros_digit(name.front())) {
    why = "must not start with a digit";
  }
  if (why == nullptr) return {};
  return vigil::unexpected(Error(
      EINVAL,
      fmt::format("node_name '{}' is not a ROS 2 node name: it {}", name.substr(0, 60), why)));
}

expected<void, Error> check_ros_namespace(std::string_view ns) {
  const char* why = nullptr;
  if (ns.empty() || ns.front() != '/') {
    why = "must start with '/' (absolute)";
  } else if (ns.size() > 245) {
    why = "is longer than 245 characters";
  } else if (ns.size() > 1 && ns.back() == '/') {
    why = "must not end with '/'";
  } else if (ns.find("//") != std::string_view::npos) {
    why = "must not hold '//'";
  } else if (!std::all_of(ns.begin(), ns.end(),
                          [](char c) { return c == '/' || ros_name_char(c); })) {
    why = "may hold only letters, digits, '_' and '/'";
  } else {
    for (std::size_t i = 0; i + 1 < ns.size(); ++i) {
      if (ns[i] == '/' && ros_digit(ns[i + 1])) why = "has a part starting with a digit";
    }
  }
  if (why == nullptr) return {};
  return vigil::unexpected(Error(
      EINVAL,
      fmt::format("node_namespace '{}' is not a ROS 2 namespace: it {}", ns.substr(0, 60), why)));
}

expected<int, Error> ros_domain_id_from_environment() {
  const char* env = std::getenv("ROS_DOMAIN_ID");
  if (env == nullptr || *env == '\0') return 0;
  return parse_ros_domain_id(env);
}

Ros2DiagnosticsOutput::Ros2DiagnosticsOutput(Ros2Options options) : options_(std::move(options)) {}

Ros2DiagnosticsOutput::~Ros2DiagnosticsOutput() {
  if (hub_ != nullptr) hub_->unsubscribe(subscription_);
  std::lock_guard lock(mutex_);
  transport_.reset();
}

void Ros2DiagnosticsOutput::fail(const std::string& why) {
  const std::string line = "ROS 2 /diagnostics: " + why;
  {
    std::lock_guard lock(mutex_);
    error_ = why;
  }
  if (options_.warn) {
    options_.warn(line);
  } else {
    std::fprintf(stderr, "vigil: %s\n", line.c_str());
  }
}

expected<void, Error> Ros2DiagnosticsOutput::start(OutputContext& context) {
  int domain = 0;
  if (options_.domain_id) {
    domain = *options_.domain_id;
    if (domain < 0 || domain > kRosDomainIdMax) {
      fail(fmt::format("domain_id {} is not a DDS domain id (0 to {}); nothing is published",
                       domain, kRosDomainIdMax));
      return {};
    }
  } else if (auto d = ros_domain_id_from_environment()) {
    domain = *d;
  } else {
    fail(d.error().message + "; nothing is published");
    return {};
  }
  domain_.store(domain, std::memory_order_relaxed);
  int gid_size = 0;
  if (options_.node) {
    if (auto n = check_ros_node_name(options_.node_name); !n) {
      fail(n.error().message + "; nothing is published");
      return {};
    }
    if (auto n = check_ros_namespace(options_.node_namespace); !n) {
      fail(n.error().message + "; nothing is published");
      return {};
    }
    const char* env = std::getenv("ROS_DISTRO");
    if (!options_.ros_distro.empty()) {
      auto g = ros_gid_size(options_.ros_distro);
      if (!g) {
        fail(g.error().message + "; nothing is published");
        return {};
      }
      gid_size = *g;
    } else if (env != nullptr && *env != '\0') {
      auto g = ros_gid_size(env, "ROS_DISTRO");
      if (!g) {
        fail(g.error().message + "; the node is announced as for Jazzy (set ros_distro)");
        gid_size = 16;
      } else {
        gid_size = *g;
      }
    } else {
      gid_size = 16;  // Jazzy
    }
  }
  auto create = load_module();
  if (!create) {
    fail(create.error());
    return {};
  }
  detail::Ros2TransportConfig config;
  config.domain_id = static_cast<std::uint32_t>(domain);
  config.config = options_.dds_config;
  if (options_.node) {
    config.node_name = options_.node_name;
    config.node_namespace = options_.node_namespace;
    config.gid_size = gid_size;
  } else {
    config.node_name.clear();
  }
  std::string why;
  std::unique_ptr<detail::Ros2Transport> t((*create)(config, &why));
  if (!t) {
    fail(fmt::format("domain {}: {}; nothing is published", domain, why));
    return {};
  }
  {
    std::lock_guard lock(mutex_);
    transport_ = std::move(t);
    if (options_.node && !transport_->node().participant_gid.empty()) {  // announced
      node_ = options_.node_namespace == "/" ? "/" + options_.node_name
                                             : options_.node_namespace + "/" + options_.node_name;
    } else {
      node_.clear();
    }
    error_.clear();
    write_failed_ = false;
  }
  gid_size_.store(options_.node ? gid_size : 0, std::memory_order_relaxed);
  active_.store(true, std::memory_order_relaxed);
  if (options_.events) {
    hub_ = &context.aggregator.events();
    subscription_ = hub_->subscribe([this](const Event& e) { on_event(e); });
  }
  return {};
}

std::int64_t Ros2DiagnosticsOutput::now_ns() const {
  if (options_.wall_clock_ns) return options_.wall_clock_ns();
  timespec ts{};
  (void)::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

bool Ros2DiagnosticsOutput::write(const DiagnosticArrayMessage& message) {
  std::string failed;
  {
    std::lock_guard lock(mutex_);
    if (!transport_) return false;
    failed = transport_->publish(message);
    if (failed.empty()) {
      write_failed_ = false;
      published_.fetch_add(1, std::memory_order_relaxed);
      return true;
    }
    if (write_failed_) return false;  // said already
    write_failed_ = true;
  }
  fail(failed);
  return false;
}

void Ros2DiagnosticsOutput::publish(const Snapshot& snapshot) {
  if (!active()) return;
  DiagnosticArrayMessage m = to_diagnostic_array(snapshot.reports, now_ns());
  (void)write(m);
  std::lock_guard lock(mutex_);
  latest_ = std::move(m);
}

void Ros2DiagnosticsOutput::on_event(const Event& e) {
  if (e.component.empty()) return;  // the hub's own events name no unit
  const std::string name = "vigil: " + e.component;
  DiagnosticArrayMessage m;
  {
    std::lock_guard lock(mutex_);
    const auto it = std::find_if(latest_.status.begin(), latest_.status.end(),
                                 [&](const DiagnosticStatusMessage& s) { return s.name == name; });
    if (it != latest_.status.end()) m.status.push_back(*it);
  }
  if (m.status.empty()) m.status.push_back(DiagnosticStatusMessage{.name = name});
  DiagnosticStatusMessage& s = m.status.front();
  s.level = std::max(s.level, event_level(e.severity));
  s.message = format_event(e);
  s.values.push_back({"event", to_string(e.kind)});
  s.values.push_back({"event_seq", std::to_string(e.seq)});
  const std::int64_t now = now_ns();
  const DiagnosticArrayMessage stamp = to_diagnostic_array(ReportSet{}, now);
  m.sec = stamp.sec;
  m.nanosec = stamp.nanosec;
  (void)write(m);
}

void Ros2DiagnosticsOutput::stop(const Snapshot& final_snapshot) {
  if (hub_ != nullptr) {
    (void)hub_->flush(kNanosPerSecond);
    hub_->unsubscribe(subscription_);
    hub_ = nullptr;
  }
  publish(final_snapshot);
  active_.store(false, std::memory_order_relaxed);
  std::lock_guard lock(mutex_);
  transport_.reset();
}

std::string Ros2DiagnosticsOutput::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

std::string Ros2DiagnosticsOutput::node() const {
  std::lock_guard lock(mutex_);
  return node_;
}

std::uint32_t Ros2DiagnosticsOutput::matched() const {
  std::lock_guard lock(mutex_);
  return transport_ ? transport_->matched() : 0;
}

std::unique_ptr<Ros2DiagnosticsOutput> make_ros2_output(Ros2Options options) {
  return std::make_unique<Ros2DiagnosticsOutput>(std::move(options));
}

}  // namespace vigil::exporter
