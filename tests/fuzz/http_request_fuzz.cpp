// Fuzz target: the HTTP endpoint (vigil::exporter::HttpServer) on arbitrary request bytes, through
// HttpServer::answer(): cpp-httplib's request parsing (request line, headers, query, body with
// its Content-Length and chunked forms, Range), the server's limits (8 KiB lines, 1 KiB body),
// the method and Host checks, the routes (Accept negotiation on /metrics, component names in
// /api/v1/reports/<name>) and the error pages: the code a connection's thread runs, without a
// socket. Two servers answer each input: a loopback one with the dashboard (Host checked) and
// one on 0.0.0.0 without it. Whatever the bytes: no crash, no sanitizer report, no 5xx other
// than the documented 503s, and a well-formed status line whenever something is answered.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "vigil/export/http_server.hpp"
#include "vigil/monitor/report.hpp"

namespace {

void check(bool ok) {
  if (!ok) __builtin_trap();
}

// /healthz must not turn stale (503) while the fuzzer runs: that would be a finding of the clock.
constexpr vigil::Nanos kNeverStale = vigil::Nanos{1} << 62;

vigil::ReportSet reports() {
  vigil::ReportSet set;
  set.cycle = 42;
  set.time_ns = 42 * vigil::kNanosPerSecond;
  const char* names[] = {"motor", "can0/arm", "a b%20c", "\xc3\xa9t\xc3\xa9"};
  std::uint32_t id = 1;
  for (const char* name : names) {
    vigil::Report r;
    r.id = id++;
    r.name = name;
    r.configured = true;
    r.activity = "periodic";
    r.period_ns = vigil::kNanosPerMilli;
    r.state = vigil::TaskState::Running;
    r.samples = 1000;
    r.port_capacity = 64;
    set.components.push_back(std::move(r));
  }
  return set;
}

struct Servers {
  vigil::exporter::HttpServer loopback{[] {
    vigil::exporter::HttpOptions o;
    o.stale_after_ns = kNeverStale;
    o.log = [](const std::string&) {};
    return o;
  }()};
  vigil::exporter::HttpServer any{[] {
    vigil::exporter::HttpOptions o;
    o.listen.host = "0.0.0.0";
    o.dashboard = false;
    o.history = 4;
    o.stale_after_ns = kNeverStale;
    o.log = [](const std::string&) {};
    return o;
  }()};
  Servers() {
    // Without its module a server answers every request 503 (saying why), and this target
    // would fuzz nothing: stop at once instead.
    check(vigil::exporter::http_module().has_value());
    loopback.publish(reports());
    any.publish(reports());
    any.publish(reports());
  }
};

void answer(vigil::exporter::HttpServer& server, std::string_view request) {
  const vigil::exporter::HttpStats before = server.stats();
  const std::string response = server.answer(request);
  if (response.empty()) return;
  // "HTTP/1.1 200 OK\r\n"; an Expect: 100-continue request gets "HTTP/1.1 100 Continue" first.
  check(response.starts_with("HTTP/1.1 ") && response.size() >= 12);
  const std::string_view code = std::string_view(response).substr(9, 3);
  check(code[0] >= '1' && code[0] <= '5' && code[1] >= '0' && code[1] <= '9' && code[2] >= '0' &&
        code[2] <= '9');
  check(response.find("\r\n\r\n") != std::string::npos);
  const vigil::exporter::HttpStats after = server.stats();
  // A 5xx is a server fault, except 503 (nothing published; the servers here have published).
  check(after.server_errors == before.server_errors);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Servers servers;
  const std::string_view request(reinterpret_cast<const char*>(data), size);
  answer(servers.loopback, request);
  answer(servers.any, request);
  return 0;
}
