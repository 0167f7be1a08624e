#pragma once
// The HTTP server's transport: what `HttpServer` (http_server.cpp, in vigil_export) asks of the
// module that speaks HTTP (http_transport.cpp, built as the loadable module `vigil_http`).
//
// Why a module: Debian's cpp-httplib is a compiled library built with TLS, zlib and brotli, so
// linking it brings OpenSSL into every process that links vigil_export, and `mlockall` makes
// all of it resident (~6.6 MB) whether or not a server is ever started. The module is the only
// object that links cpp-httplib; `HttpServer` opens it (dlopen) the first time a server starts
// or answer() is called. docs/design/memory.md has the figures.
//
// The boundary: the module parses requests and writes responses (cpp-httplib: limits, timeouts,
// HEAD, ranges, error statuses), and owns no thread and no vigil code. Everything else stays in
// vigil_export: the routes and their bodies, the worker threads (the module asks for a pool),
// the listening thread (which calls serve()). Both sides are built by the same build with the
// same compiler and C++ library, so C++ types cross it; kHttpTransportAbi and the vigil version
// guard against a module from another build.
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace vigil::exporter::detail {

/// Bumped whenever anything in this header changes.
inline constexpr int kHttpTransportAbi = 1;

/// The module's file name, and the symbols it exports (extern "C").
inline constexpr const char* kHttpModuleFile = "libvigil_http.so";
inline constexpr const char* kHttpModuleAbiSymbol = "vigil_http_transport_abi";
inline constexpr const char* kHttpModuleVersionSymbol = "vigil_http_transport_version";
inline constexpr const char* kHttpModuleCreateSymbol = "vigil_http_transport_create";

using Fields = std::vector<std::pair<std::string, std::string>>;

/// A parsed request, as the routes see it.
struct HttpRequest {
  std::string method;
  std::string path;  ///< decoded, without the query
  Fields params;     ///< the query's parameters, decoded, in order
  Fields headers;    ///< names as sent

  /// The first header named `name` (ASCII case-insensitive), or "".
  [[nodiscard]] std::string header(std::string_view name) const;
  /// The first parameter named `name`, or null.
  [[nodiscard]] const std::string* param(std::string_view name) const;
};

/// What a route answers. The module adds the default headers and Content-Length.
struct HttpResponse {
  int status = 200;
  std::string content_type;
  std::string body;
  Fields headers;  ///< added after the defaults (a name set twice is sent twice)

  void set(std::string text, std::string type) {
    body = std::move(text);
    content_type = std::move(type);
  }
};

/// The worker threads the module hands connections to.
class WorkerPool {
 public:
  virtual ~WorkerPool() = default;
  virtual void enqueue(std::function<void()> job) = 0;
  /// Serves what was queued, then joins the threads.
  virtual void shutdown() = 0;
};

struct TransportConfig {
  long read_timeout_s = 2, read_timeout_us = 0;
  long write_timeout_s = 2, write_timeout_us = 0;
  long keep_alive_timeout_s = 2;
  std::size_t max_body_bytes = 1024;
  int listen_backlog = 128;
  Fields default_headers;
  /// Every request that was parsed (whatever its method and path).
  std::function<void(const HttpRequest&, HttpResponse&)> handle;
  /// The body of an error the module itself answers (400, 408, 413, 414, 416...), and of a
  /// handled response left without a body. `path` may be empty (unparsed request line).
  std::function<std::string(int status, std::string_view path)> error_body;
  /// Called once per response written, with its status.
  std::function<void(int status)> answered;
  /// A new pool for one serve() (called from serve()).
  std::function<std::unique_ptr<WorkerPool>()> make_pool;
};

class Transport {
 public:
  virtual ~Transport() = default;
  /// Binds `host:port` (0: any free port) with SO_REUSEADDR and not SO_REUSEPORT, and listens.
  /// Returns the port bound, or -errno (-1 when no errno says why: a name that does not
  /// resolve, for example).
  virtual int bind(const std::string& host, int port) = 0;
  /// Accepts and serves connections until stop(); call once, after a successful bind().
  virtual void serve() = 0;
  /// True once serve()'s accept loop runs.
  [[nodiscard]] virtual bool serving() const = 0;
  /// Ends serve(): it returns after the connections in progress are served.
  virtual void stop() = 0;
  /// One request from raw bytes, the response as raw bytes (see HttpServer::answer()).
  virtual std::string answer(std::string_view request) = 0;
};

}  // namespace vigil::exporter::detail

extern "C" {
/// kHttpTransportAbi of the module.
using VigilHttpTransportAbiFn = int (*)();
/// The vigil version the module was built from.
using VigilHttpTransportVersionFn = const char* (*)();
/// A new transport (owned by the caller; delete it before closing the module).
using VigilHttpTransportCreateFn =
    vigil::exporter::detail::Transport* (*)(const vigil::exporter::detail::TransportConfig&);
}
