// The HTTP endpoint: requests' checks, routes and bodies. HTTP itself (parsing, limits,
// timeouts, sockets) is cpp-httplib's, in the module `vigil_http` (http_transport.cpp), which
// this file opens with dlopen the first time a server starts or answer() is called: a program
// that never serves HTTP never maps cpp-httplib and the TLS and compression libraries Debian
// builds it with (http_transport.hpp says why).
#include "vigil/export/http_server.hpp"

#include <dlfcn.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

#include "dashboard_assets.hpp"
#include "http_transport.hpp"
#include "vigil/export/diagnostics.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/json_writer.hpp"
#include "vigil/export/prometheus.hpp"
#include "vigil/export/trace_event.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/safe_state.hpp"
#include "vigil/version.hpp"

namespace vigil::exporter {

// --- addresses ---------------------------------------------------------------------------------

bool ListenAddress::loopback() const noexcept {
  return host == "localhost" || host == "::1" || host.starts_with("127.");
}

std::string ListenAddress::to_string() const {
  if (host.find(':') != std::string::npos) return fmt::format("[{}]:{}", host, port);
  return fmt::format("{}:{}", host, port);
}

expected<ListenAddress, std::string> parse_listen(std::string_view text) {
  if (text.empty()) return vigil::unexpected(std::string("empty address: expected [ADDR:]PORT"));
  ListenAddress a;
  std::string_view port = text;
  if (text.front() == '[') {
    const std::size_t close = text.find(']');
    if (close == std::string_view::npos || close + 1 >= text.size() || text[close + 1] != ':') {
      return vigil::unexpected(
          fmt::format("'{}': an IPv6 address is written [ADDR]:PORT, e.g. [::1]:9479", text));
    }
    a.host = std::string(text.substr(1, close - 1));
    port = text.substr(close + 2);
  } else if (const std::size_t colon = text.rfind(':'); colon != std::string_view::npos) {
    a.host = std::string(text.substr(0, colon));
    port = text.substr(colon + 1);
    if (a.host.find(':') != std::string::npos) {
      return vigil::unexpected(
          fmt::format("'{}': an IPv6 address is written [ADDR]:PORT, e.g. [::1]:9479", text));
    }
  }
  if (a.host.empty()) {
    return vigil::unexpected(fmt::format("'{}': the address before ':' is empty", text));
  }
  int p = -1;
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), p);
  if (port.empty() || ec != std::errc{} || end != port.data() + port.size() || p < 0 || p > 65535) {
    return vigil::unexpected(
        fmt::format("'{}': the port must be a number in 0..65535 (0: any free port)", text));
  }
  a.port = p;
  return a;
}

namespace {

// --- the worker pool: a fixed number of SCHED_OTHER threads ------------------------------------

// cpp-httplib's own pool uses std::thread, which inherits the creating thread's policy: a
// program whose main thread runs SCHED_FIFO would get real-time HTTP workers. These are created
// SCHED_OTHER explicitly; the module queues each accepted connection here.
class Pool final : public detail::WorkerPool {
 public:
  Pool(unsigned n, const std::string& name) {
    for (unsigned i = 0; i < n; ++i) {
      auto t = platform::Thread::spawn(
          platform::ThreadConfig{
              .name = name, .policy = platform::SchedPolicy::Other, .prefault_stack_bytes = 0},
          [this] { work(); });
      if (t) threads_.push_back(std::move(*t));
    }
  }
  ~Pool() override { shutdown(); }
  Pool(const Pool&) = delete;
  Pool& operator=(const Pool&) = delete;

  void enqueue(std::function<void()> fn) override {
    if (threads_.empty()) {  // no thread could be created: serve in the accepting thread
      fn();
      return;
    }
    {
      std::lock_guard lock(mutex_);
      jobs_.push_back(std::move(fn));
    }
    cv_.notify_one();
  }

  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      if (stop_) return;
      stop_ = true;
    }
    cv_.notify_all();
    for (auto& t : threads_) t.join();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [&] { return stop_ || !jobs_.empty(); });
        if (jobs_.empty()) return;  // stopping, and every accepted connection was served
        fn = std::move(jobs_.front());
        jobs_.pop_front();
      }
      fn();
    }
  }

  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> jobs_;
  bool stop_ = false;
  std::vector<platform::Thread> threads_;
};

// --- JSON bodies -------------------------------------------------------------------------------

void write_buckets(exporter::JsonWriter& w, const BucketCounts& b) {
  w.begin_object();
  w.key("buckets").begin_array();
  std::uint64_t below = 0;
  for (std::size_t i = 0; i < kBucketBounds; ++i) {
    w.value(b.cumulative[i] - below);
    below = b.cumulative[i];
  }
  w.value(b.count - below);  // above the last boundary
  w.end_array();
  w.field("count", b.count);
  w.field("sum_s", b.sum_ns / 1e9);
  w.end_object();
}

std::string histograms_json(const MetricsSnapshot& s) {
  exporter::JsonWriter w;
  w.begin_object();
  w.field("schema", 2);
  w.field("cycle", s.reports.cycle);
  w.key("bounds_s").begin_array();
  for (Nanos b : kBucketBoundsNs) w.value(static_cast<double>(b) / 1e9);
  w.end_array();
  w.key("components").begin_array();
  for (const ComponentHistograms& h : s.histograms) {
    w.begin_object();
    w.field("name", h.name);
    w.field("id", h.id);
    w.key("execution");
    write_buckets(w, h.execution);
    w.key("total");
    write_buckets(w, h.total);
    w.key("latency");
    write_buckets(w, h.latency);
    w.key("measured_period");
    write_buckets(w, h.measured_period);
    w.end_object();
  }
  w.end_array();
  w.end_object();
  return w.take();
}

std::string history_json(const MetricsSnapshot& s) {
  exporter::JsonWriter w;
  w.begin_object();
  w.field("schema", 1);
  w.field("cycle", s.reports.cycle);
  const Nanos newest = s.history.empty() ? 0 : s.history.back()->time_ns;
  w.key("time_s").begin_array();
  for (const auto& f : s.history) w.value(static_cast<double>(f->time_ns - newest) / 1e9);
  w.end_array();
  w.key("cycles").begin_array();
  for (const auto& f : s.history) w.value(f->cycle);
  w.end_array();
  // Components in the order of the newest frame; a component absent from a frame is null there.
  w.key("components").begin_object();
  if (!s.history.empty()) {
    for (const HistoryPoint& c : s.history.back()->points) {
      std::vector<const HistoryPoint*> at;
      at.reserve(s.history.size());
      for (const auto& f : s.history) {
        const auto it = std::find_if(f->points.begin(), f->points.end(),
                                     [&](const HistoryPoint& p) { return p.name == c.name; });
        at.push_back(it == f->points.end() ? nullptr : &*it);
      }
      const auto series = [&](std::string_view key, auto get) {
        w.key(key).begin_array();
        for (const HistoryPoint* p : at) {
          if (p == nullptr) {
            w.null();
          } else {
            w.value(get(*p));
          }
        }
        w.end_array();
      };
      w.key(c.name).begin_object();
      series("execution_p99_s",
             [](const HistoryPoint& p) { return static_cast<double>(p.execution_p99_ns) / 1e9; });
      series("latency_p99_s",
             [](const HistoryPoint& p) { return static_cast<double>(p.latency_p99_ns) / 1e9; });
      series("overruns", [](const HistoryPoint& p) { return p.overruns; });
      series("window_overruns", [](const HistoryPoint& p) { return p.window_overruns; });
      series("status", [](const HistoryPoint& p) { return static_cast<int>(p.status); });
      w.end_object();
    }
  }
  w.end_object();
  w.end_object();
  return w.take();
}

std::string component_json(const MetricsSnapshot& s, const Report& r) {
  exporter::JsonWriter w;
  w.begin_object();
  w.field("schema", exporter::kJsonSchemaVersion);
  w.field("generator", std::string("vigil ") + kVersion);
  w.field("cycle", s.reports.cycle);
  w.field("time_ns", s.reports.time_ns);
  w.key("component");
  write_json(w, r);
  w.end_object();
  return w.take();
}

std::string error_json(std::string_view message) {
  exporter::JsonWriter w;
  w.begin_object().field("error", message).end_object();
  return w.take();
}

// A published snapshot with its bodies, each rendered on first request and then shared.
struct Published {
  std::shared_ptr<const MetricsSnapshot> snap;

  struct Body {
    std::once_flag once;
    std::string text;
  };
  mutable Body prometheus, openmetrics, reports, diagnostics, histograms, history;

  template <class F>
  const std::string& get(Body& b, F render) const {
    std::call_once(b.once, [&] { b.text = render(); });
    return b.text;
  }
};

// The JSON documents of a snapshot, each rendered at most once per snapshot.
struct JsonDocument {
  std::string_view path;
  const std::string& (*body)(const Published&);
};

const JsonDocument kJsonDocuments[] = {
    {"/api/v1/reports",
     [](const Published& p) -> const std::string& {
       return p.get(p.reports, [&] { return to_json(p.snap->reports); });
     }},
    {"/api/v1/diagnostics",
     [](const Published& p) -> const std::string& {
       return p.get(p.diagnostics,
                    [&] { return to_diagnostics_json(p.snap->reports, p.snap->wall_time_ns); });
     }},
    {"/api/v1/histograms",
     [](const Published& p) -> const std::string& {
       return p.get(p.histograms, [&] { return histograms_json(*p.snap); });
     }},
    {"/api/v1/history",
     [](const Published& p) -> const std::string& {
       return p.get(p.history, [&] { return history_json(*p.snap); });
     }},
};

constexpr int kListenBacklog = 128;
constexpr const char* kJson = "application/json; charset=utf-8";
constexpr const char* kText = "text/plain; charset=utf-8";

const char* reason(int status) {
  switch (status) {
    case 400:
      return "bad request";
    case 403:
      return "forbidden";
    case 404:
      return "not found";
    case 405:
      return "method not allowed";
    case 408:
      return "request timeout";
    case 413:
      return "payload too large";
    case 414:
      return "URI too long";
    case 416:
      return "range not satisfiable";
    case 500:
      return "internal server error";
    case 503:
      return "service unavailable";
    default:
      return "error";
  }
}

// Host header check for loopback servers (DNS rebinding): the host part must be a loopback name.
bool loopback_host(std::string_view host) {
  if (host.empty()) return true;  // HTTP/1.0 without Host
  if (host.front() == '[') {
    const std::size_t close = host.find(']');
    return close != std::string_view::npos && host.substr(1, close - 1) == "::1";
  }
  if (const std::size_t colon = host.rfind(':'); colon != std::string_view::npos) {
    host = host.substr(0, colon);
  }
  return host == "localhost" || host.starts_with("127.");
}

// --- the module -------------------------------------------------------------------------------

// One module per process, opened on first use and never closed (a transport's code must stay
// mapped while any transport lives; the module holds no state of its own).
struct Module {
  VigilHttpTransportCreateFn create = nullptr;
  std::string path;
};

// Opens `path` and checks that it is a vigil HTTP module of this build.
expected<Module, std::string> open_module(const std::string& path) {
  void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = ::dlerror();
    return vigil::unexpected(why != nullptr ? std::string(why) : path + ": cannot be opened");
  }
  const auto abi =
      reinterpret_cast<VigilHttpTransportAbiFn>(::dlsym(handle, detail::kHttpModuleAbiSymbol));
  const auto version = reinterpret_cast<VigilHttpTransportVersionFn>(
      ::dlsym(handle, detail::kHttpModuleVersionSymbol));
  const auto create = reinterpret_cast<VigilHttpTransportCreateFn>(
      ::dlsym(handle, detail::kHttpModuleCreateSymbol));
  std::string wrong;
  if (abi == nullptr || version == nullptr || create == nullptr) {
    wrong =
        fmt::format("{}: not a vigil HTTP module (no {})", path, detail::kHttpModuleCreateSymbol);
  } else if (abi() != detail::kHttpTransportAbi || std::strcmp(version(), kVersion) != 0) {
    wrong = fmt::format(
        "{}: built from vigil {} (interface {}), this program is vigil {} (interface "
        "{})",
        path, version(), abi(), kVersion, detail::kHttpTransportAbi);
  }
  if (!wrong.empty()) {
    (void)::dlclose(handle);
    return vigil::unexpected(std::move(wrong));
  }
  // The file actually opened (a bare name was found through the dynamic linker's search).
  Dl_info info{};
  const bool found = ::dladdr(reinterpret_cast<void*>(create), &info) != 0 &&
                     info.dli_fname != nullptr && *info.dli_fname != '\0';
  return Module{.create = create, .path = found ? std::string(info.dli_fname) : path};
}

// Where the module is looked for, in order (docs/reference/http.md, "The HTTP module").
std::vector<std::string> module_candidates() {
  if (const char* env = std::getenv("VIGIL_HTTP_MODULE"); env != nullptr && *env != '\0') {
    return {env};  // an explicit choice: nothing else is tried
  }
  std::vector<std::string> c;
  // The dynamic linker's search: the program's RUNPATH (the installed `vigil` has
  // $ORIGIN/../lib/vigil, and find_package(vigil) adds the installation's), LD_LIBRARY_PATH,
  // the system's directories.
  c.emplace_back(detail::kHttpModuleFile);
#ifdef VIGIL_HTTP_MODULE_BUILD_PATH
  // This build tree's module: what tests and the tool run from the build tree load.
  if (::access(VIGIL_HTTP_MODULE_BUILD_PATH, F_OK) == 0)
    c.emplace_back(VIGIL_HTTP_MODULE_BUILD_PATH);
#endif
#ifdef VIGIL_HTTP_MODULE_INSTALL_PATH
  c.emplace_back(VIGIL_HTTP_MODULE_INSTALL_PATH);  // where `cmake --install` puts it by default
#endif
  return c;
}

std::mutex module_mutex;
std::optional<Module> loaded_module;  // guarded by module_mutex

expected<Module, Error> load_module() {
  std::lock_guard lock(module_mutex);
  if (loaded_module) return *loaded_module;
  std::string tried;
  for (const std::string& path : module_candidates()) {
    auto m = open_module(path);
    if (m) {
      loaded_module = *m;
      return *m;
    }
    tried += "\n  " + m.error();
  }
  return vigil::unexpected(
      Error(ENOENT, fmt::format("HTTP server: cannot load its module {} (set VIGIL_HTTP_MODULE to "
                                "its path; see docs/reference/http.md):{}",
                                detail::kHttpModuleFile, tried)));
}

std::string endpoint_list() {
  return "endpoints: /, /metrics, /api/v1/reports, /api/v1/reports/<name>, /api/v1/diagnostics, "
         "/api/v1/histograms, /api/v1/history, /healthz";
}

std::string error_text(int status, std::string_view path) {
  if (status == 404) {
    return fmt::format("404 not found: {} ({})\n", path.substr(0, 200), endpoint_list());
  }
  return fmt::format("{} {}\n", status, reason(status));
}

}  // namespace

expected<std::string, Error> http_module() {
  auto m = load_module();
  if (!m) return vigil::unexpected(m.error());
  return m->path;
}

// --- the server --------------------------------------------------------------------------------

struct HttpServer::Impl {
  HttpOptions options;
  detail::TransportConfig transport_config;
  std::unique_ptr<detail::Transport> transport;
  std::mutex memory_mutex;                    // creates `memory` once
  std::unique_ptr<detail::Transport> memory;  // answer()'s transport: no socket
  platform::Thread listener;
  std::mutex control_mutex;  // serialises start() and stop()
  std::atomic<bool> running{false};
  ListenAddress bound;
  std::string page;  // the dashboard (or the index) with its settings filled in

  mutable std::mutex snapshot_mutex;  // guards current; held for a pointer copy
  std::shared_ptr<const Published> current;

  std::mutex publish_mutex;  // serialises publish(); guards the fields below
  std::deque<std::shared_ptr<const HistoryFrame>> history;
  Nanos previous_publication = 0;
  std::atomic<Nanos> interval{0};

  std::atomic<std::uint64_t> requests{0}, client_errors{0}, server_errors{0}, publications{0};

  explicit Impl(HttpOptions o);

  void log(const std::string& line) const {
    if (options.log) {
      options.log(line);
    } else {
      std::fprintf(stderr, "%s\n", line.c_str());
    }
  }

  std::shared_ptr<const Published> published() const {
    std::lock_guard lock(snapshot_mutex);
    return current;
  }

  Nanos stale_limit() const {
    if (options.stale_after_ns > 0) return options.stale_after_ns;
    return std::max<Nanos>(3 * interval.load(std::memory_order_relaxed), 3 * kNanosPerSecond);
  }

  // A new transport from the module, with this server's limits, timeouts and routes.
  expected<std::unique_ptr<detail::Transport>, Error> make_transport();

  // Every request: method and Host checks, then the routes.
  void handle(const detail::HttpRequest& req, detail::HttpResponse& res);
  void route(const detail::HttpRequest& req, detail::HttpResponse& res);
  bool json_503(detail::HttpResponse& res, const std::shared_ptr<const Published>& p) const;
  // The routes, in the order route() tries them; those that return bool say whether `path` was
  // theirs.
  void clear_faults(const detail::HttpRequest& req, detail::HttpResponse& res);
  bool dashboard_file(const std::string& path, detail::HttpResponse& res) const;
  void metrics(const detail::HttpRequest& req, detail::HttpResponse& res) const;
  bool json_document(const std::string& path, detail::HttpResponse& res) const;
  void report_of(const std::string& name, detail::HttpResponse& res) const;
  void trace_of(const std::string& name, detail::HttpResponse& res) const;
  void event_trace(std::string_view seq, detail::HttpResponse& res) const;
  void events(const detail::HttpRequest& req, detail::HttpResponse& res);
  void healthz(detail::HttpResponse& res);
};

namespace {

std::string index_page() {
  return "<!doctype html><meta charset=utf-8><title>vigil</title><h1>vigil</h1><ul>"
         "<li><a href=/metrics>/metrics</a> Prometheus / OpenMetrics</li>"
         "<li><a href=/api/v1/reports>/api/v1/reports</a> reports (JSON schema 2)</li>"
         "<li><a href=/api/v1/diagnostics>/api/v1/diagnostics</a> ROS 2 DiagnosticArray</li>"
         "<li><a href=/api/v1/histograms>/api/v1/histograms</a> timing histograms</li>"
         "<li><a href=/api/v1/history>/api/v1/history</a> recent p99s and overruns</li>"
         "<li><a href=/healthz>/healthz</a></li></ul>\n";
}

void replace_all(std::string& s, std::string_view from, std::string_view to) {
  for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) {
    s.replace(p, from.size(), to);
  }
}

bool iequal(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

}  // namespace

std::string detail::HttpRequest::header(std::string_view name) const {
  for (const auto& [k, v] : headers) {
    if (iequal(k, name)) return v;
  }
  return {};
}

const std::string* detail::HttpRequest::param(std::string_view name) const {
  for (const auto& [k, v] : params) {
    if (k == name) return &v;
  }
  return nullptr;
}

HttpServer::Impl::Impl(HttpOptions o) : options(std::move(o)) {
  if (options.dashboard) {
    page = std::string(detail::kDashboardHtml);
    replace_all(page, "{{REFRESH_MS}}",
                std::to_string(options.dashboard_refresh_ns / kNanosPerMilli));
    replace_all(page, "{{CHARTS}}", detail::kChartJs.empty() ? "0" : "1");
    replace_all(page, "{{VERSION}}", kVersion);
  } else {
    page = index_page();
  }
  detail::TransportConfig& c = transport_config;
  const HttpOptions& op = options;
  c.keep_alive_timeout_s =
      std::max<long>(1, static_cast<long>(op.read_timeout_ns / kNanosPerSecond));
  c.read_timeout_s = static_cast<long>(op.read_timeout_ns / kNanosPerSecond);
  c.read_timeout_us = static_cast<long>((op.read_timeout_ns % kNanosPerSecond) / 1000);
  c.write_timeout_s = static_cast<long>(op.write_timeout_ns / kNanosPerSecond);
  c.write_timeout_us = static_cast<long>((op.write_timeout_ns % kNanosPerSecond) / 1000);
  c.max_body_bytes = op.max_body_bytes;
  c.listen_backlog = kListenBacklog;
  c.default_headers = {{"X-Content-Type-Options", "nosniff"},
                       {"Cache-Control", "no-store"},
                       {"Referrer-Policy", "no-referrer"}};
  c.handle = [this](const detail::HttpRequest& req, detail::HttpResponse& res) {
    handle(req, res);
  };
  c.error_body = [](int status, std::string_view path) { return error_text(status, path); };
  c.answered = [this](int status) {
    requests.fetch_add(1, std::memory_order_relaxed);
    if (status >= 500) {
      server_errors.fetch_add(1, std::memory_order_relaxed);
    } else if (status >= 400) {
      client_errors.fetch_add(1, std::memory_order_relaxed);
    }
  };
  c.make_pool = [threads = op.threads, name = op.thread_name] {
    return std::make_unique<Pool>(threads, name);
  };
}

expected<std::unique_ptr<detail::Transport>, Error> HttpServer::Impl::make_transport() {
  auto module = load_module();
  if (!module) return vigil::unexpected(module.error());
  std::unique_ptr<detail::Transport> t(module->create(transport_config));
  if (!t) {
    return vigil::unexpected(Error(
        ENOMEM, fmt::format("HTTP server: the module {} could not create a server", module->path)));
  }
  return t;
}

void HttpServer::Impl::handle(const detail::HttpRequest& req, detail::HttpResponse& res) {
  const bool clear_post = options.clear && req.method == "POST" && req.path == "/api/v1/clear";
  if (req.method != "GET" && req.method != "HEAD" && !clear_post) {
    res.status = 405;
    res.headers.emplace_back("Allow", "GET, HEAD");
    res.set(fmt::format("405 method not allowed: {} (this endpoint is read-only: GET and HEAD)\n",
                        req.method),
            kText);
    return;
  }
  if (options.listen.loopback() && !loopback_host(req.header("Host"))) {
    res.status = 403;
    res.set(
        "403 forbidden: this server listens on a loopback address and answers "
        "only requests for localhost, 127.0.0.1 or [::1]\n",
        kText);
    return;
  }
  try {
    route(req, res);
  } catch (const std::exception& e) {
    res = detail::HttpResponse{};
    res.status = 500;
    res.set(std::string("500 internal server error: ") + e.what() + "\n", kText);
  }
}

bool HttpServer::Impl::json_503(detail::HttpResponse& res,
                                const std::shared_ptr<const Published>& p) const {
  if (p) return false;
  res.status = 503;
  res.set(error_json("no reports yet: the monitor has not published a cycle"), kJson);
  return true;
}

void HttpServer::Impl::route(const detail::HttpRequest& req, detail::HttpResponse& res) {
  const std::string& path = req.path;
  if (req.method == "POST") {  // handle() let only POST /api/v1/clear through, when enabled
    clear_faults(req, res);
    return;
  }
  if (dashboard_file(path, res)) return;
  if (path == "/metrics") {
    metrics(req, res);
    return;
  }
  if (json_document(path, res)) return;
  constexpr std::string_view kReportOf = "/api/v1/reports/";
  if (path.size() > kReportOf.size() && path.starts_with(kReportOf)) {
    report_of(path.substr(kReportOf.size()), res);
    return;
  }
  if (path == "/api/v1/events" && options.events != nullptr) {
    events(req, res);
    return;
  }
  constexpr std::string_view kEventPrefix = "/api/v1/events/";
  constexpr std::string_view kTraceSuffix = "/trace";
  if (options.event_trace && path.size() > kEventPrefix.size() + kTraceSuffix.size() &&
      path.starts_with(kEventPrefix) && path.ends_with(kTraceSuffix)) {
    const std::string_view p(path);
    event_trace(p.substr(kEventPrefix.size(), p.size() - kEventPrefix.size() - kTraceSuffix.size()),
                res);
    return;
  }
  constexpr std::string_view kTraceOf = "/api/v1/trace/";
  if (options.trace && path.size() > kTraceOf.size() && path.starts_with(kTraceOf)) {
    trace_of(path.substr(kTraceOf.size()), res);
    return;
  }
  if (path == "/healthz") {
    healthz(res);
    return;
  }
  res.status = 404;
  res.set(error_text(404, path), kText);
}

void HttpServer::Impl::clear_faults(const detail::HttpRequest& req, detail::HttpResponse& res) {
  if (req.header("X-Vigil-Clear") != "1") {
    res.status = 403;
    res.set(error_json("POST /api/v1/clear needs the header X-Vigil-Clear: 1"), kJson);
    return;
  }
  const std::string* name = req.param("component");
  const std::string* safe = req.param("safe_state");
  if (safe != nullptr && *safe != "1") {
    res.status = 400;
    res.set(error_json("safe_state must be 1 (end the safe-state request) or absent"), kJson);
    return;
  }
  const std::size_t n = options.clear(name != nullptr ? *name : std::string());
  if (safe != nullptr) {
    // The operator's decision to leave the safe state (vigil/safe_state.hpp): never vigil's own.
    const bool ended = vigil::clear_safe_state();
    res.set(fmt::format(R"({{"cleared":{},"safe_state_cleared":{}}})", n, ended) + "\n", kJson);
    return;
  }
  res.set(fmt::format(R"({{"cleared":{}}})", n) + "\n", kJson);
}

bool HttpServer::Impl::dashboard_file(const std::string& path, detail::HttpResponse& res) const {
  if (path == "/") {
    res.headers.emplace_back(
        "Content-Security-Policy",
        "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
        "frame-ancestors 'none'");
    res.set(page, "text/html; charset=utf-8");
    return true;
  }
  if (!options.dashboard) return false;
  if (path == "/static/dashboard.js") {
    res.set(std::string(detail::kDashboardJs), "text/javascript; charset=utf-8");
    return true;
  }
  if (path == "/static/dashboard.css") {
    res.set(std::string(detail::kDashboardCss), "text/css; charset=utf-8");
    return true;
  }
  if (path == "/static/chart.js" && !detail::kChartJs.empty()) {
    res.headers.emplace_back("Cache-Control", "max-age=86400");
    res.set(std::string(detail::kChartJs), "text/javascript; charset=utf-8");
    return true;
  }
  return false;
}

void HttpServer::Impl::metrics(const detail::HttpRequest& req, detail::HttpResponse& res) const {
  const ExpositionFormat f = negotiate_format(req.header("Accept"));
  auto p = published();
  if (!p) {
    res.set(render_metrics(MetricsSnapshot{}, f), content_type(f));
    return;
  }
  const std::string& body =
      f == ExpositionFormat::OpenMetrics
          ? p->get(p->openmetrics, [&] { return render_metrics(*p->snap, f); })
          : p->get(p->prometheus, [&] { return render_metrics(*p->snap, f); });
  res.set(body, content_type(f));
}

bool HttpServer::Impl::json_document(const std::string& path, detail::HttpResponse& res) const {
  for (const JsonDocument& d : kJsonDocuments) {
    if (path != d.path) continue;
    auto p = published();
    if (!json_503(res, p)) res.set(d.body(*p), kJson);
    return true;
  }
  return false;
}

void HttpServer::Impl::report_of(const std::string& name, detail::HttpResponse& res) const {
  auto p = published();
  if (json_503(res, p)) return;
  const Report* r = p->snap->reports.find(name);
  if (r == nullptr) {
    res.status = 404;
    res.set(error_json("no component named '" + name + "'"), kJson);
    return;
  }
  res.set(component_json(*p->snap, *r), kJson);
}

void HttpServer::Impl::trace_of(const std::string& name, detail::HttpResponse& res) const {
  auto body = options.trace(name);
  if (!body) {
    res.status = 404;
    res.set(error_json("no component named '" + name + "'"), kJson);
    return;
  }
  res.headers.emplace_back("Content-Disposition", "attachment; filename=\"vigil-trace.json\"");
  res.set(std::move(*body), kJson);
}

void HttpServer::Impl::event_trace(std::string_view seq, detail::HttpResponse& res) const {
  std::uint64_t n = 0;
  const auto [end, ec] = std::from_chars(seq.data(), seq.data() + seq.size(), n);
  if (ec != std::errc{} || end != seq.data() + seq.size() || n == 0) {
    res.status = 404;
    res.set(error_json("not an event sequence number: '" + std::string(seq) + "'"), kJson);
    return;
  }
  auto body = options.event_trace(n);
  if (!body) {
    res.status = 404;
    res.set(error_json(fmt::format("no flight record kept for event {}", n)), kJson);
    return;
  }
  res.headers.emplace_back("Content-Disposition",
                           fmt::format("attachment; filename=\"vigil-event-{}.trace.json\"", n));
  res.set(std::move(*body), kJson);
}

void HttpServer::Impl::events(const detail::HttpRequest& req, detail::HttpResponse& res) {
  supervisor::EventHub& hub = *options.events;
  std::uint64_t after = 0;
  double wait_s = 0;
  try {
    if (const std::string* a = req.param("after")) after = std::stoull(*a);
    if (const std::string* w = req.param("wait")) wait_s = std::stod(*w);
  } catch (const std::exception&) {
    res.status = 400;
    res.set(error_json("after must be an event sequence number and wait a number of seconds"),
            kJson);
    return;
  }
  if (!(wait_s >= 0)) wait_s = 0;
  const Nanos wait_ns = std::min(static_cast<Nanos>(wait_s * 1e9), options.events_max_wait_ns);
  if (wait_ns > 0) (void)hub.wait(after, wait_ns);
  const auto list = hub.since(after, 1000);
  std::string body =
      fmt::format(R"({{"last_seq":{},"lost_before":{},"events":[)", hub.last_seq(),
                  !list.empty() && list.front().seq > after + 1 ? list.front().seq - after - 1 : 0);
  for (std::size_t i = 0; i < list.size(); ++i) {
    if (i > 0) body += ',';
    body += event_json(list[i]);
  }
  body += "]}\n";
  res.set(std::move(body), kJson);
}

void HttpServer::Impl::healthz(detail::HttpResponse& res) {
  auto p = published();
  exporter::JsonWriter w;
  w.begin_object();
  if (!p) {
    res.status = 503;
    w.field("status", "starting").field("detail", "no reports published yet");
  } else {
    const Nanos age = platform::now_ns() - p->snap->published_ns;
    const bool stale = age > stale_limit();
    // The pipeline's own threads: the supervisor (STALE when it stopped draining), the monitor
    // (STALE when its reports are older than the limit) and the reaction thread (ERROR while a
    // handler runs over its budget).
    std::vector<std::pair<std::string_view, StatusLevel>> threads;
    bool stalled = false;
    for (const monitor::Report& r : p->snap->reports.components) {
      StatusLevel level = r.status.level();
      if (r.kind == monitor::ReportKind::Monitor && stale) level = StatusLevel::Stale;
      if (r.kind == monitor::ReportKind::Supervisor || r.kind == monitor::ReportKind::Monitor) {
        stalled = stalled || level == StatusLevel::Stale;
      } else if (r.is_unit("reactions")) {
        stalled = stalled || level == StatusLevel::Error;
      } else {
        continue;
      }
      threads.emplace_back(r.name, level);
    }
    res.status = stale || stalled ? 503 : 200;
    w.field("status", stale ? "stale" : stalled ? "stalled" : "ok");
    w.field("cycle", p->snap->reports.cycle);
    w.field("age_s", static_cast<double>(age) / 1e9);
    w.field("stale_after_s", static_cast<double>(stale_limit()) / 1e9);
    w.field("worst", to_string(p->snap->reports.worst()));
    w.key("threads").begin_object();
    for (const auto& [name, level] : threads) w.field(name, to_string(level));
    w.end_object();
  }
  w.end_object();
  res.set(w.take() + "\n", kJson);
}

HttpServer::HttpServer(HttpOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

HttpServer::~HttpServer() { stop(); }

expected<void, Error> HttpServer::start() {
  Impl& m = *impl_;
  std::lock_guard control(m.control_mutex);
  const HttpOptions& o = m.options;
  if (m.running) return vigil::unexpected(Error("HTTP server: already running"));
  if (o.threads < 1 || o.threads > 16) {
    return vigil::unexpected(
        Error(EINVAL, fmt::format("HTTP server: threads must be in 1..16, not {}", o.threads)));
  }
  if (o.listen.port < 0 || o.listen.port > 65535) {
    return vigil::unexpected(
        Error(EINVAL, fmt::format("HTTP server: port {} is not in 0..65535", o.listen.port)));
  }
  if (o.dashboard_refresh_ns < 200 * kNanosPerMilli || o.dashboard_refresh_ns > kNanosPerSecond) {
    return vigil::unexpected(
        Error(EINVAL, "HTTP server: the dashboard refresh must be 200 ms..1 s (1 to 5 Hz)"));
  }

  auto made = m.make_transport();
  if (!made) return vigil::unexpected(made.error());
  m.transport = std::move(*made);
  const int port = m.transport->bind(o.listen.host, o.listen.port);
  if (port <= 0) {
    const int err = -port;
    const std::string what =
        err == EADDRINUSE ? "the port is taken (another process serves it); choose another port"
        : err > 1         ? std::string(std::strerror(err))
                          : std::string("cannot resolve or bind");
    m.transport.reset();
    return vigil::unexpected(
        Error(err > 1 ? err : 0,
              fmt::format("HTTP server: cannot listen on {}: {}", o.listen.to_string(), what)));
  }
  m.bound = ListenAddress{o.listen.host, port};

  auto t = platform::Thread::spawn(
      platform::ThreadConfig{
          .name = o.thread_name, .policy = platform::SchedPolicy::Other, .prefault_stack_bytes = 0},
      [tr = m.transport.get()] { tr->serve(); });
  if (!t) {
    m.transport.reset();
    return vigil::unexpected(
        Error(t.error().code, "HTTP server: cannot start its thread: " + t.error().message));
  }
  m.listener = std::move(*t);
  // stop() only stops a server whose accept loop has begun: wait for it (a few ms).
  for (int i = 0; i < 2000 && !m.transport->serving(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  m.running = true;
  m.log(fmt::format("vigil: HTTP on {} (dashboard /, Prometheus /metrics, JSON /api/v1/reports)",
                    url()));
  if (!m.bound.loopback()) {
    m.log(
        fmt::format("vigil: warning: HTTP listens on {}, not on loopback only: every host that "
                    "can reach this one can read the reports (no authentication; see "
                    "docs/guide/http.md)",
                    m.bound.to_string()));
  }
  return {};
}

void HttpServer::stop() {
  Impl& m = *impl_;
  std::lock_guard control(m.control_mutex);
  if (!m.running) return;
  if (m.options.events != nullptr) m.options.events->cancel_waits();  // end the long polls
  m.transport->stop();
  m.listener.join();
  m.transport.reset();
  m.running = false;
}

bool HttpServer::running() const noexcept { return impl_->running; }

std::string HttpServer::answer(std::string_view request) {
  Impl& m = *impl_;
  detail::Transport* t = nullptr;
  {
    std::lock_guard lock(m.memory_mutex);
    if (!m.memory) {
      auto made = m.make_transport();
      if (!made) {
        // As a server that cannot serve would answer: 503, saying why.
        const std::string body = made.error().message + "\n";
        return fmt::format(
            "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\n"
            "Content-Length: {}\r\nConnection: close\r\n\r\n{}",
            body.size(), body);
      }
      m.memory = std::move(*made);
    }
    t = m.memory.get();
  }
  return t->answer(request);
}

ListenAddress HttpServer::address() const { return impl_->bound; }

std::string HttpServer::url() const {
  ListenAddress a = impl_->bound;
  if (a.host == "0.0.0.0") a.host = "127.0.0.1";
  if (a.host == "::") a.host = "::1";
  return "http://" + a.to_string() + "/";
}

void HttpServer::publish(const ReportSet& reports, std::vector<ComponentHistograms> histograms,
                         std::vector<CanHistograms> can_histograms,
                         std::vector<CanBusLoads> can_buses) {
  Impl& m = *impl_;
  auto snap = std::make_shared<MetricsSnapshot>();
  snap->reports = reports;
  snap->histograms = std::move(histograms);
  std::sort(snap->histograms.begin(), snap->histograms.end(),
            [](const auto& a, const auto& b) { return a.id < b.id; });
  snap->can_histograms = std::move(can_histograms);
  std::sort(snap->can_histograms.begin(), snap->can_histograms.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  snap->can_buses = std::move(can_buses);
  std::sort(snap->can_buses.begin(), snap->can_buses.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  snap->wall_time_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                           std::chrono::system_clock::now().time_since_epoch())
                           .count();
  snap->published_ns = platform::now_ns();
  {
    std::lock_guard lock(m.publish_mutex);
    if (m.options.history > 0) {
      m.history.push_back(std::make_shared<const HistoryFrame>(make_history_frame(reports)));
      while (m.history.size() > m.options.history) m.history.pop_front();
    }
    snap->history.assign(m.history.begin(), m.history.end());
    if (m.previous_publication != 0) {
      m.interval.store(snap->published_ns - m.previous_publication, std::memory_order_relaxed);
    }
    m.previous_publication = snap->published_ns;
  }
  auto p = std::make_shared<Published>();
  p->snap = std::move(snap);
  std::shared_ptr<const Published> old;
  {
    std::lock_guard lock(m.snapshot_mutex);
    old = std::move(m.current);
    m.current = std::move(p);
  }
  m.publications.fetch_add(1, std::memory_order_relaxed);
  // `old` is released here, outside the lock (or later by the last request that holds it).
}

std::shared_ptr<const MetricsSnapshot> HttpServer::snapshot() const {
  auto p = impl_->published();
  return p ? p->snap : nullptr;
}

HttpStats HttpServer::stats() const noexcept {
  const Impl& m = *impl_;
  return HttpStats{.requests = m.requests.load(std::memory_order_relaxed),
                   .client_errors = m.client_errors.load(std::memory_order_relaxed),
                   .server_errors = m.server_errors.load(std::memory_order_relaxed),
                   .publications = m.publications.load(std::memory_order_relaxed)};
}

const HttpOptions& HttpServer::options() const noexcept { return impl_->options; }

}  // namespace vigil::exporter
