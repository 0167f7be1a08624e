// The HTTP endpoint on cpp-httplib 0.11 (Debian's libcpp-httplib, a compiled library: its
// compile-time limits are the package's: 8 KiB request line and header line, backlog 5).
//
// cpp-httplib pulls the socket headers in; the only socket call made here is the SO_REUSEADDR
// option that replaces cpp-httplib's default (which also sets SO_REUSEPORT, letting a second
// server silently share the port).
#include "vigil/export/http_server.hpp"

#include <fmt/format.h>
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>

#include "dashboard_assets.hpp"
#include "vigil/export/diagnostics.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/json_writer.hpp"
#include "vigil/export/prometheus.hpp"
#include "vigil/export/trace_event.hpp"
#include "vigil/platform/thread.hpp"
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
// SCHED_OTHER explicitly.
class Pool final : public httplib::TaskQueue {
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
  w.field("schema", 1);
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
    w.key("period");
    write_buckets(w, h.period);
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

// cpp-httplib's server with one request served from any Stream (process_request is protected):
// what a connection's thread runs, used on an in-memory stream by HttpServer::answer().
class Server final : public httplib::Server {
 public:
  bool serve_one(httplib::Stream& stream) {
    bool closed = false;
    // As on a connection with keep-alive count 1: the request is the connection's last.
    return process_request(stream, true, closed, nullptr);
  }
};

// A connection in memory: reads the request's bytes, collects the response's.
class MemoryStream final : public httplib::Stream {
 public:
  explicit MemoryStream(std::string_view in) : in_(in) {}
  bool is_readable() const override { return true; }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override {
    const std::size_t n = std::min(size, in_.size() - pos_);
    std::memcpy(ptr, in_.data() + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    out_.append(ptr, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = "127.0.0.1";
    port = 40000;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = "127.0.0.1";
    port = kDefaultHttpPort;
  }
  socket_t socket() const override { return INVALID_SOCKET; }
  std::string take() { return std::move(out_); }

 private:
  std::string_view in_;
  std::size_t pos_ = 0;
  std::string out_;
};

}  // namespace

// --- the server --------------------------------------------------------------------------------

struct HttpServer::Impl {
  HttpOptions options;
  std::unique_ptr<Server> server;
  std::mutex memory_mutex;         // creates `memory` once
  std::unique_ptr<Server> memory;  // answer()'s server: the same configuration, no socket
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

  // Everything a server does with a request: limits, timeouts, checks and routes.
  void configure(Server& s);
  void routes(Server& s);
};

namespace {

std::string index_page() {
  return "<!doctype html><meta charset=utf-8><title>vigil</title><h1>vigil</h1><ul>"
         "<li><a href=/metrics>/metrics</a> Prometheus / OpenMetrics</li>"
         "<li><a href=/api/v1/reports>/api/v1/reports</a> reports (JSON schema 1)</li>"
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

}  // namespace

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
}

void HttpServer::Impl::configure(Server& s) {
  const HttpOptions& o = options;
  s.set_keep_alive_max_count(1);  // one request per connection: no thread held between requests
  s.set_keep_alive_timeout(
      std::max<time_t>(1, static_cast<time_t>(o.read_timeout_ns / kNanosPerSecond)));
  s.set_read_timeout(o.read_timeout_ns / kNanosPerSecond,
                     (o.read_timeout_ns % kNanosPerSecond) / 1000);
  s.set_write_timeout(o.write_timeout_ns / kNanosPerSecond,
                      (o.write_timeout_ns % kNanosPerSecond) / 1000);
  s.set_payload_max_length(o.max_body_bytes);
  routes(s);
}

void HttpServer::Impl::routes(Server& s) {
  using HR = httplib::Server::HandlerResponse;
  const bool check_host = options.listen.loopback();

  const bool clear_enabled = static_cast<bool>(options.clear);
  s.set_pre_routing_handler([check_host, clear_enabled](const httplib::Request& req,
                                                        httplib::Response& res) {
    const bool clear_post = clear_enabled && req.method == "POST" && req.path == "/api/v1/clear";
    if (req.method != "GET" && req.method != "HEAD" && !clear_post) {
      res.status = 405;
      res.set_header("Allow", "GET, HEAD");
      res.set_content(fmt::format("405 method not allowed: {} (this endpoint is read-only: GET "
                                  "and HEAD)\n",
                                  req.method),
                      kText);
      return HR::Handled;
    }
    if (check_host && !loopback_host(req.get_header_value("Host"))) {
      res.status = 403;
      res.set_content(
          "403 forbidden: this server listens on a loopback address and answers "
          "only requests for localhost, 127.0.0.1 or [::1]\n",
          kText);
      return HR::Handled;
    }
    return HR::Unhandled;
  });
  s.set_error_handler(
      httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return HR::Unhandled;
        if (res.status == 404) {
          res.set_content(fmt::format("404 not found: {} (endpoints: /, /metrics, /api/v1/reports, "
                                      "/api/v1/reports/<name>, /api/v1/diagnostics, "
                                      "/api/v1/histograms, /api/v1/history, /healthz)\n",
                                      req.path.size() > 200 ? req.path.substr(0, 200) : req.path),
                          kText);
        } else {
          res.set_content(fmt::format("{} {}\n", res.status, reason(res.status)), kText);
        }
        return HR::Handled;
      }));
  s.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, const std::exception_ptr& ep) {
        std::string what = "unknown exception";
        try {
          if (ep) std::rethrow_exception(ep);
        } catch (const std::exception& e) {
          what = e.what();
        } catch (...) {
        }
        res.status = 500;
        res.set_content("500 internal server error: " + what + "\n", kText);
      });
  s.set_logger([this](const httplib::Request&, const httplib::Response& res) {
    requests.fetch_add(1, std::memory_order_relaxed);
    if (res.status >= 500) {
      server_errors.fetch_add(1, std::memory_order_relaxed);
    } else if (res.status >= 400) {
      client_errors.fetch_add(1, std::memory_order_relaxed);
    }
  });
  s.set_default_headers({{"X-Content-Type-Options", "nosniff"},
                         {"Cache-Control", "no-store"},
                         {"Referrer-Policy", "no-referrer"}});

  // The dashboard and its files.
  s.Get("/", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
                   "frame-ancestors 'none'");
    res.set_content(page, "text/html; charset=utf-8");
  });
  if (options.dashboard) {
    s.Get("/static/dashboard.js", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(std::string(detail::kDashboardJs), "text/javascript; charset=utf-8");
    });
    s.Get("/static/dashboard.css", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(std::string(detail::kDashboardCss), "text/css; charset=utf-8");
    });
    if (!detail::kChartJs.empty()) {
      s.Get("/static/chart.js", [](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "max-age=86400");
        res.set_content(std::string(detail::kChartJs), "text/javascript; charset=utf-8");
      });
    }
  }

  s.Get("/metrics", [this](const httplib::Request& req, httplib::Response& res) {
    const ExpositionFormat f = negotiate_format(req.get_header_value("Accept"));
    auto p = published();
    if (!p) {
      res.set_content(render_metrics(MetricsSnapshot{}, f), content_type(f));
      return;
    }
    const std::string& body =
        f == ExpositionFormat::OpenMetrics
            ? p->get(p->openmetrics, [&] { return render_metrics(*p->snap, f); })
            : p->get(p->prometheus, [&] { return render_metrics(*p->snap, f); });
    res.set_content(body, content_type(f));
  });

  const auto json_endpoint = [this](auto body_of) {
    return [this, body_of](const httplib::Request&, httplib::Response& res) {
      auto p = published();
      if (!p) {
        res.status = 503;
        res.set_content(error_json("no reports yet: the monitor has not published a cycle"), kJson);
        return;
      }
      res.set_content(body_of(*p), kJson);
    };
  };
  s.Get("/api/v1/reports", json_endpoint([](const Published& p) -> const std::string& {
          return p.get(p.reports, [&] { return to_json(p.snap->reports); });
        }));
  s.Get("/api/v1/diagnostics", json_endpoint([](const Published& p) -> const std::string& {
          return p.get(p.diagnostics,
                       [&] { return to_diagnostics_json(p.snap->reports, p.snap->wall_time_ns); });
        }));
  s.Get("/api/v1/histograms", json_endpoint([](const Published& p) -> const std::string& {
          return p.get(p.histograms, [&] { return histograms_json(*p.snap); });
        }));
  s.Get("/api/v1/history", json_endpoint([](const Published& p) -> const std::string& {
          return p.get(p.history, [&] { return history_json(*p.snap); });
        }));
  s.Get(R"(/api/v1/reports/(.+))", [this](const httplib::Request& req, httplib::Response& res) {
    auto p = published();
    if (!p) {
      res.status = 503;
      res.set_content(error_json("no reports yet: the monitor has not published a cycle"), kJson);
      return;
    }
    const std::string name = req.matches[1];
    const Report* r = p->snap->reports.find(name);
    if (r == nullptr) {
      res.status = 404;
      res.set_content(error_json("no component named '" + name + "'"), kJson);
      return;
    }
    res.set_content(component_json(*p->snap, *r), kJson);
  });

  if (options.events != nullptr) {
    s.Get("/api/v1/events", [this](const httplib::Request& req, httplib::Response& res) {
      supervisor::EventHub& hub = *options.events;
      std::uint64_t after = 0;
      double wait_s = 0;
      try {
        if (req.has_param("after")) after = std::stoull(req.get_param_value("after"));
        if (req.has_param("wait")) wait_s = std::stod(req.get_param_value("wait"));
      } catch (const std::exception&) {
        res.status = 400;
        res.set_content(error_json("after must be an event sequence number and wait a number "
                                   "of seconds"),
                        kJson);
        return;
      }
      if (!(wait_s >= 0)) wait_s = 0;
      const Nanos wait_ns = std::min(static_cast<Nanos>(wait_s * 1e9), options.events_max_wait_ns);
      if (wait_ns > 0) (void)hub.wait(after, wait_ns);
      const auto events = hub.since(after, 1000);
      std::string body = fmt::format(
          R"({{"last_seq":{},"lost_before":{},"events":[)", hub.last_seq(),
          !events.empty() && events.front().seq > after + 1 ? events.front().seq - after - 1 : 0);
      for (std::size_t i = 0; i < events.size(); ++i) {
        if (i > 0) body += ',';
        body += event_json(events[i]);
      }
      body += "]}\n";
      res.set_content(body, kJson);
    });
  }
  if (options.trace) {
    s.Get(R"(/api/v1/trace/(.+))", [this](const httplib::Request& req, httplib::Response& res) {
      const std::string name = req.matches[1];
      auto body = options.trace(name);
      if (!body) {
        res.status = 404;
        res.set_content(error_json("no component named '" + name + "'"), kJson);
        return;
      }
      res.set_header("Content-Disposition", "attachment; filename=\"vigil-trace.json\"");
      res.set_content(*body, kJson);
    });
  }
  if (options.clear) {
    s.Post("/api/v1/clear", [this](const httplib::Request& req, httplib::Response& res) {
      if (req.get_header_value("X-Vigil-Clear") != "1") {
        res.status = 403;
        res.set_content(error_json("POST /api/v1/clear needs the header X-Vigil-Clear: 1"), kJson);
        return;
      }
      const std::string name = req.has_param("component") ? req.get_param_value("component") : "";
      const std::size_t n = options.clear(name);
      res.set_content(fmt::format(R"({{"cleared":{}}})", n) + "\n", kJson);
    });
  }

  s.Get("/healthz", [this](const httplib::Request&, httplib::Response& res) {
    auto p = published();
    exporter::JsonWriter w;
    w.begin_object();
    if (!p) {
      res.status = 503;
      w.field("status", "starting").field("detail", "no reports published yet");
    } else {
      const Nanos age = platform::now_ns() - p->snap->published_ns;
      const bool stale = age > stale_limit();
      res.status = stale ? 503 : 200;
      w.field("status", stale ? "stale" : "ok");
      w.field("cycle", p->snap->reports.cycle);
      w.field("age_s", static_cast<double>(age) / 1e9);
      w.field("stale_after_s", static_cast<double>(stale_limit()) / 1e9);
      w.field("worst", to_string(p->snap->reports.worst()));
    }
    w.end_object();
    res.set_content(w.take() + "\n", kJson);
  });
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

  m.server = std::make_unique<Server>();
  Server& s = *m.server;
  // SO_REUSEADDR (restart while old connections linger in TIME_WAIT) but not SO_REUSEPORT:
  // a second server on the same port must fail, not share the port.
  // The hook also remembers the socket, whose listen backlog is raised after the bind.
  auto last_socket = std::make_shared<std::atomic<socket_t>>(INVALID_SOCKET);
  s.set_socket_options([last_socket](socket_t sock) {
    int yes = 1;
    (void)::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    last_socket->store(sock);
  });
  const unsigned threads = o.threads;
  const std::string name = o.thread_name;
  s.new_task_queue = [threads, name] { return new Pool(threads, name); };
  m.configure(s);

  errno = 0;
  int port = o.listen.port;
  bool bound = false;
  if (port == 0) {
    port = s.bind_to_any_port(o.listen.host);
    bound = port > 0;
  } else {
    bound = s.bind_to_port(o.listen.host, port);
  }
  if (!bound) {
    const int err = errno;
    const std::string what =
        err == EADDRINUSE ? "the port is taken (another process serves it); choose another port"
        : err != 0        ? std::string(std::strerror(err))
                          : std::string("cannot resolve or bind");
    m.server.reset();
    return vigil::unexpected(Error(
        err, fmt::format("HTTP server: cannot listen on {}: {}", o.listen.to_string(), what)));
  }
  m.bound = ListenAddress{o.listen.host, port};
  // Debian's cpp-httplib listens with a backlog of 5: a burst of scrapers (or a browser opening
  // several connections) would see dropped SYNs and retransmission delays of seconds. Linux
  // updates the backlog of a listening socket when listen() is called again.
  if (const socket_t sock = last_socket->load(); sock != INVALID_SOCKET) {
    (void)::listen(sock, kListenBacklog);
  }

  auto t = platform::Thread::spawn(
      platform::ThreadConfig{
          .name = o.thread_name, .policy = platform::SchedPolicy::Other, .prefault_stack_bytes = 0},
      [srv = m.server.get()] { srv->listen_after_bind(); });
  if (!t) {
    m.server.reset();
    return vigil::unexpected(
        Error(t.error().code, "HTTP server: cannot start its thread: " + t.error().message));
  }
  m.listener = std::move(*t);
  // stop() only stops a server whose accept loop has begun: wait for it (a few ms).
  for (int i = 0; i < 2000 && !m.server->is_running(); ++i) {
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
  m.server->stop();
  m.listener.join();
  m.server.reset();
  m.running = false;
}

bool HttpServer::running() const noexcept { return impl_->running; }

std::string HttpServer::answer(std::string_view request) {
  Impl& m = *impl_;
  Server* s = nullptr;
  {
    std::lock_guard lock(m.memory_mutex);
    if (!m.memory) {
      m.memory = std::make_unique<Server>();
      m.configure(*m.memory);
    }
    s = m.memory.get();
  }
  MemoryStream stream(request);
  (void)s->serve_one(stream);
  return stream.take();
}

ListenAddress HttpServer::address() const { return impl_->bound; }

std::string HttpServer::url() const {
  ListenAddress a = impl_->bound;
  if (a.host == "0.0.0.0") a.host = "127.0.0.1";
  if (a.host == "::") a.host = "::1";
  return "http://" + a.to_string() + "/";
}

void HttpServer::publish(const ReportSet& reports, std::vector<ComponentHistograms> histograms,
                         std::vector<CanHistograms> can_histograms) {
  Impl& m = *impl_;
  auto snap = std::make_shared<MetricsSnapshot>();
  snap->reports = reports;
  snap->histograms = std::move(histograms);
  std::sort(snap->histograms.begin(), snap->histograms.end(),
            [](const auto& a, const auto& b) { return a.id < b.id; });
  snap->can_histograms = std::move(can_histograms);
  std::sort(snap->can_histograms.begin(), snap->can_histograms.end(),
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
