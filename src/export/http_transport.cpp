// The module `vigil_http` (libvigil_http.so): HTTP on cpp-httplib 0.11, for HttpServer.
// http_transport.hpp says why this is a module and what crosses the boundary.
//
// Debian's libcpp-httplib is a compiled library: its compile-time limits are the package's (8 KiB
// request line and header line, listen backlog 5, raised here after the bind). cpp-httplib pulls
// the socket headers in; the only socket calls made here are the SO_REUSEADDR option that
// replaces cpp-httplib's default (which also sets SO_REUSEPORT, letting a second server silently
// share the port) and the listen() that raises the backlog.
#include "http_transport.hpp"

#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <exception>
#include <mutex>

#include "vigil/version.hpp"

namespace vigil::exporter::detail {
namespace {

// cpp-httplib's task queue on the pool HttpServer gives: its threads are vigil's (SCHED_OTHER,
// named, with a set stack), not std::threads inheriting the caller's real-time policy.
class Queue final : public httplib::TaskQueue {
 public:
  explicit Queue(std::unique_ptr<WorkerPool> pool) : pool_(std::move(pool)) {}
  void enqueue(std::function<void()> fn) override { pool_->enqueue(std::move(fn)); }
  void shutdown() override { pool_->shutdown(); }

 private:
  std::unique_ptr<WorkerPool> pool_;
};

// cpp-httplib's server with one request served from any Stream (process_request is protected):
// what a connection's thread runs, used on an in-memory stream by answer().
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
    port = 9479;
  }
  socket_t socket() const override { return INVALID_SOCKET; }
  std::string take() { return std::move(out_); }

 private:
  std::string_view in_;
  std::size_t pos_ = 0;
  std::string out_;
};

HttpRequest request_of(const httplib::Request& req) {
  HttpRequest r;
  r.method = req.method;
  r.path = req.path;
  r.params.reserve(req.params.size());
  for (const auto& [k, v] : req.params) r.params.emplace_back(k, v);
  r.headers.reserve(req.headers.size());
  for (const auto& [k, v] : req.headers) r.headers.emplace_back(k, v);
  return r;
}

void configure(Server& s, const TransportConfig& c) {
  using HR = httplib::Server::HandlerResponse;
  s.set_keep_alive_max_count(1);  // one request per connection: no thread held between requests
  s.set_keep_alive_timeout(c.keep_alive_timeout_s);
  s.set_read_timeout(c.read_timeout_s, c.read_timeout_us);
  s.set_write_timeout(c.write_timeout_s, c.write_timeout_us);
  s.set_payload_max_length(c.max_body_bytes);
  httplib::Headers defaults;
  for (const auto& [k, v] : c.default_headers) defaults.emplace(k, v);
  s.set_default_headers(std::move(defaults));

  // Every parsed request goes to HttpServer's routes; cpp-httplib's own routing is not used.
  s.set_pre_routing_handler([&c](const httplib::Request& req, httplib::Response& res) {
    HttpResponse out;
    c.handle(request_of(req), out);
    res.status = out.status;
    for (auto& [k, v] : out.headers) res.set_header(k, v);
    if (!out.body.empty() || !out.content_type.empty()) res.set_content(out.body, out.content_type);
    return HR::Handled;
  });
  s.set_error_handler(httplib::Server::HandlerWithResponse(
      [&c](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return HR::Unhandled;
        res.set_content(c.error_body(res.status, req.path), "text/plain; charset=utf-8");
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
        res.set_content("500 internal server error: " + what + "\n", "text/plain; charset=utf-8");
      });
  s.set_logger(
      [&c](const httplib::Request&, const httplib::Response& res) { c.answered(res.status); });
}

class HttplibTransport final : public Transport {
 public:
  explicit HttplibTransport(TransportConfig config) : config_(std::move(config)) {
    configure(server_, config_);
    // SO_REUSEADDR (restart while old connections linger in TIME_WAIT) but not SO_REUSEPORT:
    // a second server on the same port must fail, not share the port. The hook also remembers
    // the socket, whose listen backlog is raised after the bind.
    server_.set_socket_options([this](socket_t sock) {
      int yes = 1;
      (void)::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
      socket_.store(sock);
    });
    server_.new_task_queue = [this] { return new Queue(config_.make_pool()); };
  }

  int bind(const std::string& host, int port) override {
    errno = 0;
    bool bound = false;
    if (port == 0) {
      port = server_.bind_to_any_port(host);
      bound = port > 0;
    } else {
      bound = server_.bind_to_port(host, port);
    }
    if (!bound) return errno != 0 ? -errno : -1;
    // Debian's cpp-httplib listens with a backlog of 5: a burst of scrapers (or a browser
    // opening several connections) would see dropped SYNs and retransmission delays of
    // seconds. Linux updates the backlog of a listening socket when listen() is called again.
    if (const socket_t sock = socket_.load(); sock != INVALID_SOCKET) {
      (void)::listen(sock, config_.listen_backlog);
    }
    return port;
  }

  void serve() override { (void)server_.listen_after_bind(); }
  bool serving() const override { return server_.is_running(); }
  void stop() override { server_.stop(); }

  std::string answer(std::string_view request) override {
    Server* s = nullptr;
    {
      std::lock_guard lock(memory_mutex_);
      if (!memory_) {
        memory_ = std::make_unique<Server>();
        configure(*memory_, config_);
      }
      s = memory_.get();
    }
    MemoryStream stream(request);
    (void)s->serve_one(stream);
    return stream.take();
  }

 private:
  TransportConfig config_;
  Server server_;
  std::atomic<socket_t> socket_{INVALID_SOCKET};
  std::mutex memory_mutex_;         // creates `memory_` once
  std::unique_ptr<Server> memory_;  // answer()'s server: the same configuration, no socket
};

}  // namespace
}  // namespace vigil::exporter::detail

extern "C" {

__attribute__((visibility("default"))) int vigil_http_transport_abi() {
  return vigil::exporter::detail::kHttpTransportAbi;
}

__attribute__((visibility("default"))) const char* vigil_http_transport_version() {
  return vigil::kVersion;
}

__attribute__((visibility("default"))) vigil::exporter::detail::Transport*
vigil_http_transport_create(const vigil::exporter::detail::TransportConfig& config) {
  try {
    return new vigil::exporter::detail::HttplibTransport(config);
  } catch (...) {
    return nullptr;
  }
}

}  // extern "C"
