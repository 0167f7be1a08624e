#pragma once
/// @file
/// `HttpServer`: vigil's read-only HTTP endpoint (cpp-httplib): Prometheus/OpenMetrics
/// `/metrics`, the JSON and ROS-diagnostics APIs, `/healthz`, and the live dashboard at `/`.
/// docs/reference/http.md lists every endpoint; docs/guide/http.md shows how to use them.
///
/// Design:
///  - **Copy-on-publish.** A publisher (normally the monitor's thread, through
///    `exporter::HttpOutput`, see outputs.hpp) hands over each cycle's reports with
///    `publish()`, which builds an immutable
///    `MetricsSnapshot` and swaps a `shared_ptr` under a mutex held for the swap only. HTTP
///    threads take a reference to the current snapshot and render from it (each body is
///    rendered once per snapshot and shared by every request that asks for it). Nothing here
///    touches the real-time side; a client can neither stop nor slow the publisher.
///  - **Safe defaults.** Binds 127.0.0.1 unless told otherwise (and says so when told); refuses
///    to start when the port is taken (no SO_REUSEPORT sharing); a small fixed pool of
///    SCHED_OTHER threads; no keep-alive (a connection cannot hold a thread between requests);
///    read and write timeouts; a request body limit; GET and HEAD only (others 405), unknown
///    paths 404, malformed or oversized requests 4xx; on a loopback address, requests whose
///    Host is not a loopback name are refused (403) so that a web page cannot read the
///    endpoint through DNS rebinding.
///
///  - **Loaded on demand.** HTTP itself is cpp-httplib's, which Debian builds with OpenSSL, zlib
///    and brotli; it lives in the module `libvigil_http.so`, opened the first time a server
///    starts or answer() is called. A program that never serves HTTP never maps those libraries
///    (with memory locked, they would cost ~6.6 MB of RAM). Where the module is looked for:
///    http_module(), and docs/reference/http.md.
///
/// Thread safety: every member is thread-safe. Nothing here is RT-safe.
///
/// @code
/// vigil::exporter::HttpServer http({.listen = {"127.0.0.1", 9479}});
/// if (auto ok = http.start(); !ok) std::fprintf(stderr, "%s\n", ok.error().message.c_str());
/// monitor.subscribe([&](const vigil::ReportSet& r) { http.publish(r); });
/// @endcode

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/metrics_snapshot.hpp"
#include "vigil/monitor/report.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/supervisor/events.hpp"

namespace vigil::exporter {

/// The port used when none is given (unassigned; pick another with `--http PORT`).
inline constexpr int kDefaultHttpPort = 9479;

/// Where a server listens.
struct ListenAddress {
  std::string host = "127.0.0.1";  ///< IPv4 or IPv6 literal, or a host name
  int port = kDefaultHttpPort;     ///< 0: any free port (see HttpServer::address())

  /// True for 127.0.0.0/8, ::1 and "localhost".
  [[nodiscard]] bool loopback() const noexcept;
  /// "127.0.0.1:9479", "[::1]:9479".
  [[nodiscard]] std::string to_string() const;
};

/// Parses "[ADDR:]PORT": "9479", "127.0.0.1:9479", "0.0.0.0:9479", "[::1]:9479",
/// "localhost:9479". Without an address the host is 127.0.0.1. Fails with a message naming what
/// is wrong (empty, port not a number or not in 0..65535, an IPv6 address without brackets).
[[nodiscard]] expected<ListenAddress, std::string> parse_listen(std::string_view text);

/// Opens the HTTP module if it is not open yet and returns the path it was opened from. Looked
/// for, in order: `$VIGIL_HTTP_MODULE` when set (then nothing else); `libvigil_http.so`
/// through the dynamic linker's search (the program's RUNPATH, which find_package(vigil) and
/// the installed `vigil` point at the installation's `<libdir>/vigil`, `LD_LIBRARY_PATH`, the
/// system's directories); this build tree's module (programs run from the build tree); the
/// default installation's `<libdir>/vigil/libvigil_http.so`. A module from another vigil version is
/// refused. Fails naming every path tried and why each was refused; HttpServer::start() fails
/// with the same message. Once open, the module stays open. Thread-safe; not RT-safe (it opens
/// files). With memory locked (`mlockall`, MCL_FUTURE), the module and its libraries are locked
/// when they are opened.
[[nodiscard]] expected<std::string, Error> http_module();

/// Options of the server.
struct HttpOptions {
  ListenAddress listen;
  /// Worker threads (1..16): each serves one connection at a time.
  unsigned threads = 3;
  /// Serve the dashboard at `/` (and its scripts under /static/); else `/` lists the endpoints.
  bool dashboard = true;
  /// Seconds a client may take to send each part of a request, or to read the response.
  Nanos read_timeout_ns = 2 * kNanosPerSecond;
  Nanos write_timeout_ns = 2 * kNanosPerSecond;
  /// Longest request body accepted (requests are GETs: no body is needed); longer ones get 413.
  std::size_t max_body_bytes = 1024;
  /// Monitor cycles kept for the dashboard's history charts.
  std::size_t history = 120;
  /// How often the dashboard refreshes, 200 ms..1 s (1 to 5 Hz).
  Nanos dashboard_refresh_ns = 500 * kNanosPerMilli;
  /// /healthz answers 503 when the newest reports are older than this; 0: three times the
  /// interval between the two latest publications, at least 3 s.
  Nanos stale_after_ns = 0;
  /// Name of the server's threads (at most 15 characters are kept).
  std::string thread_name = "vigil-http";
  /// Events served at `GET /api/v1/events?after=SEQ&wait=SECONDS` (a long poll; null: the
  /// endpoint answers 404). The hub must outlive the server.
  supervisor::EventHub* events = nullptr;
  /// Longest wait of an events long poll (a request asking more gets this).
  Nanos events_max_wait_ns = 25 * kNanosPerSecond;
  /// `POST /api/v1/clear[?component=NAME]` clears latched faults through this function (the
  /// name, or empty for all; returns how many were latched). The one write endpoint: off
  /// (405, like any other POST) unless set. The request must carry the header
  /// `X-Vigil-Clear: 1` (a browser cannot send it cross-origin without a preflight, which this
  /// server never grants).
  std::function<std::size_t(const std::string&)> clear;
  /// `GET /api/v1/trace/<name>`: the component's flight recorder now, as trace-event JSON
  /// (empty optional: unknown component, 404). Null: the endpoint answers 404.
  std::function<std::optional<std::string>(const std::string&)> trace;
  /// `GET /api/v1/events/<seq>/trace`: the flight record frozen with event `seq` (the `trace`
  /// of an OpenMetrics exemplar) as trace-event JSON (empty optional: no such record kept,
  /// 404). Null: the endpoint answers 404.
  std::function<std::optional<std::string>(std::uint64_t)> event_trace;
  /// Where start() writes what it did ("serving on ..." and, for a non-loopback address, a
  /// warning). Empty: standard error.
  std::function<void(const std::string&)> log;
};

/// Counters of the server (since start).
struct HttpStats {
  std::uint64_t requests = 0;       ///< requests answered (any status)
  std::uint64_t client_errors = 0;  ///< 4xx answers
  std::uint64_t server_errors = 0;  ///< 5xx answers
  std::uint64_t publications = 0;   ///< snapshots published
};

class HttpServer {
 public:
  /// A stopped server with `options` (validated by start()).
  explicit HttpServer(HttpOptions options = {});
  /// Stops the server if it runs.
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Binds and starts serving. Fails (nothing left running) when the options are invalid, the
  /// address cannot be resolved, or the port is taken ("address already in use": another
  /// process serves it; no port sharing). Logs the URL, and a warning when the address is not
  /// loopback. Not idempotent: fails when already running.
  expected<void, Error> start();
  /// Stops accepting, lets the requests in progress finish (bounded by the timeouts) and joins
  /// the threads. Idempotent.
  void stop();
  [[nodiscard]] bool running() const noexcept;

  /// Answers one request given as the raw bytes a client would send on a connection
  /// ("GET /metrics HTTP/1.1\r\nHost: localhost\r\n\r\n"): the same request parsing (cpp-httplib),
  /// limits, method and Host checks, routes and error pages as a connection of the running
  /// server, without any socket; whether or not the server runs. Returns the raw response
  /// (status line, headers, body), empty when the bytes hold no request line (the connection
  /// would be closed without an answer). Counted in stats(). When the HTTP module cannot be
  /// opened, a 503 response whose body says why (not counted). For tests and fuzzing
  /// (tests/fuzz/http_request_fuzz.cpp). Thread-safe; not RT-safe.
  [[nodiscard]] std::string answer(std::string_view request);

  /// The address actually bound (the chosen port when the options asked for 0). Valid after a
  /// successful start().
  [[nodiscard]] ListenAddress address() const;
  /// "http://127.0.0.1:9479/" (after start()).
  [[nodiscard]] std::string url() const;

  /// Publishes one monitor cycle: copies `reports`, takes `histograms` (by component id, may be
  /// empty), `can_histograms` (the CAN reports' gap buckets, by name, may be empty) and
  /// `can_buses` (the CAN bus reports' loads, by name, may be empty), appends
  /// a history frame, and swaps the snapshot served. Call from one publisher thread at a time
  /// (calls are serialised). Works whether or not the server runs.
  void publish(const ReportSet& reports, std::vector<ComponentHistograms> histograms = {},
               std::vector<CanHistograms> can_histograms = {},
               std::vector<CanBusLoads> can_buses = {});
  /// The snapshot being served (null before the first publish()).
  [[nodiscard]] std::shared_ptr<const MetricsSnapshot> snapshot() const;

  [[nodiscard]] HttpStats stats() const noexcept;
  [[nodiscard]] const HttpOptions& options() const noexcept;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace vigil::exporter
