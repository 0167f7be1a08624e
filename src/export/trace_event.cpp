#include "vigil/export/trace_event.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <system_error>

#include "vigil/export/json_writer.hpp"

namespace vigil::exporter {

namespace {

double us(Nanos ns) { return static_cast<double>(ns) / 1e3; }

// Component names become file names: keep letters, digits, '-', '_' and '.'.
std::string file_stem(std::string_view name) {
  std::string out;
  for (const char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_' || c == '.';
    out += ok ? c : '_';
  }
  if (out.empty() || out[0] == '.') out.insert(out.begin(), '_');
  return out;
}

void meta(exporter::JsonWriter& w, const char* what, int pid, int tid, const std::string& name) {
  w.begin_object()
      .field("name", what)
      .field("ph", "M")
      .field("pid", pid)
      .field("tid", tid)
      .key("args")
      .begin_object()
      .field("name", name)
      .end_object()
      .end_object();
}

// Where the events of a record go in the viewer: the component's process and thread.
struct Track {
  int pid = 0;
  int tid = 0;
};

// Names the process and the thread (with the activity, policy, priority and period if known).
void write_names(exporter::JsonWriter& w, const supervisor::FlightRecord& r, Track t) {
  meta(w, "process_name", t.pid, t.tid, "vigil: " + r.component);
  std::string thread = r.component;
  if (r.has_info) {
    thread += fmt::format(
        " ({}, {} {}, period {} us)", r.info.activity.empty() ? "-" : r.info.activity.view(),
        platform::to_string(r.info.policy), r.info.priority, r.info.period_ns / kNanosPerMicro);
  }
  meta(w, "thread_name", t.pid, t.tid, thread);
}

// One cycle: a mark for the cycles missing before it (`prev`: the cycle before it, or null), its
// slice, and its latency and user time as counters.
void write_cycle(exporter::JsonWriter& w, const supervisor::CycleRecord& c,
                 const supervisor::CycleRecord* prev, Track t) {
  const bool overrun = (c.flags & supervisor::CycleRecord::kOverrun) != 0;
  if (prev != nullptr && c.cycle != prev->cycle + 1) {
    w.begin_object()
        .field("name", fmt::format("{} cycles missing (dropped)", c.cycle - prev->cycle - 1))
        .field("ph", "i")
        .field("s", "t")
        .field("ts", us(c.start_ns))
        .field("pid", t.pid)
        .field("tid", t.tid)
        .end_object();
  }
  w.begin_object();
  w.field("name", overrun ? "cycle (overrun)" : "cycle");
  w.field("cat", overrun ? "cycle,overrun" : "cycle");
  w.field("ph", "X");
  w.field("ts", us(c.start_ns));
  w.field("dur", us(c.end_ns - c.start_ns));
  w.field("pid", t.pid).field("tid", t.tid);
  w.key("args").begin_object();
  w.field("cycle", c.cycle);
  w.field("release_us", us(c.release_ns));
  w.field("latency_us", us(c.latency_ns()));
  w.field("execution_us", us(c.execution_ns()));
  w.field("overhead_us", us(c.overhead_ns));
  w.field("overrun", overrun);
  w.field("missed_before", c.missed_before);
  w.field("warmup", (c.flags & supervisor::CycleRecord::kWarmup) != 0);
  // Only on the rare records the flight ring could not keep to the nanosecond.
  if ((c.flags & supervisor::CycleRecord::kCoarse) != 0) w.field("microsecond_precision", true);
  if ((c.flags & supervisor::CycleRecord::kClipped) != 0) w.field("clipped", true);
  w.field("state", to_string(c.state));
  w.end_object();
  w.end_object();
  w.begin_object()
      .field("name", "latency_us")
      .field("ph", "C")
      .field("ts", us(c.start_ns))
      .field("pid", t.pid)
      .key("args")
      .begin_object()
      .field("latency_us", us(c.latency_ns()))
      .end_object()
      .end_object();
  w.begin_object()
      .field("name", "execution_us")
      .field("ph", "C")
      .field("ts", us(c.start_ns))
      .field("pid", t.pid)
      .key("args")
      .begin_object()
      .field("execution_us", us(c.execution_ns()))
      .end_object()
      .end_object();
}

// The fault that froze the record: for a deadline the silence before it, then the fault and its
// detection as instants.
void write_fault(exporter::JsonWriter& w, const supervisor::FlightRecord& r, Track t) {
  const Event& e = r.event;
  Nanos at = e.fault_ns;
  if (at == 0 && !r.cycles.empty()) at = r.cycles.back().end_ns;
  if (e.kind == EventKind::Deadline && !r.cycles.empty()) {
    // The silence: from the last cycle's end to the detection.
    const Nanos from = r.cycles.back().end_ns;
    w.begin_object()
        .field("name", "no cycle (silent)")
        .field("cat", "fault")
        .field("ph", "X")
        .field("ts", us(from))
        .field("dur", us(std::max<Nanos>(e.detected_ns - from, 0)))
        .field("pid", t.pid)
        .field("tid", t.tid)
        .end_object();
  }
  w.begin_object();
  w.field("name", fmt::format("{}: {}", to_string(e.kind), e.detail));
  w.field("cat", "fault");
  w.field("ph", "i");
  w.field("s", "p");
  w.field("ts", us(at));
  w.field("pid", t.pid).field("tid", t.tid);
  w.key("args").begin_object();
  w.field("cycle", e.cycle);
  w.field("severity", to_string(e.severity));
  w.field("detected_us", us(e.detected_ns));
  w.field("latency_us", us(e.latency_ns()));
  w.end_object();
  w.end_object();
  w.begin_object()
      .field("name", "detected")
      .field("cat", "fault")
      .field("ph", "i")
      .field("s", "t")
      .field("ts", us(e.detected_ns))
      .field("pid", t.pid)
      .field("tid", t.tid)
      .end_object();
}

// Health supervision: each checkpoint as an instant on the component's thread, and each deadline
// supervision's start/end pairs as async slices (one track per supervision; a missed deadline
// ends at its max and says so).
void write_health(exporter::JsonWriter& w, const supervisor::FlightRecord& r, Track t) {
  for (const health::CheckpointMark& m : r.checkpoints) {
    w.begin_object()
        .field("name", m.name)
        .field("cat", "checkpoint")
        .field("ph", "i")
        .field("s", "t")
        .field("ts", us(m.time_ns))
        .field("pid", t.pid)
        .field("tid", t.tid)
        .key("args")
        .begin_object()
        .field("cycle", m.cycle)
        .end_object()
        .end_object();
  }
  std::uint64_t id = 1;
  for (const health::DeadlineSpan& d : r.deadlines) {
    const bool ok = d.failure == health::FailureKind::None;
    const std::string name = fmt::format("deadline {}", d.supervision);
    w.begin_object()
        .field("name", name)
        .field("cat", ok ? "deadline" : "deadline,fault")
        .field("ph", "b")
        .field("id", id)
        .field("ts", us(d.start_ns))
        .field("pid", t.pid)
        .field("tid", t.tid)
        .key("args")
        .begin_object()
        .field("start", d.start)
        .field("end", d.end)
        .field("duration_us", us(d.end_ns - d.start_ns))
        .field("result", ok ? "ok" : health::to_string(d.failure))
        .end_object()
        .end_object();
    w.begin_object()
        .field("name", name)
        .field("cat", ok ? "deadline" : "deadline,fault")
        .field("ph", "e")
        .field("id", id)
        .field("ts", us(d.end_ns))
        .field("pid", t.pid)
        .field("tid", t.tid)
        .end_object();
    ++id;
  }
}

// What the record is about, for the viewer's metadata panel.
void write_other_data(exporter::JsonWriter& w, const supervisor::FlightRecord& r) {
  const Event& e = r.event;
  w.begin_object();
  w.field("component", r.component);
  w.field("reason", r.on_demand ? std::string("on demand")
                                : fmt::format("{}: {}", to_string(e.kind), e.detail));
  w.field("event_seq", e.seq);
  w.field("fault_cycle", e.cycle);
  w.field("fault_ns", e.fault_ns);
  w.field("detected_ns", e.detected_ns);
  w.field("frozen_ns", r.frozen_ns);
  w.field("cycles", static_cast<std::uint64_t>(r.cycles.size()));
  w.field("checkpoints", static_cast<std::uint64_t>(r.checkpoints.size()));
  w.field("deadline_spans", static_cast<std::uint64_t>(r.deadlines.size()));
  w.end_object();
}

}  // namespace

std::string event_json(const Event& e) {
  std::string out = fmt::format(R"({{"seq":{},"kind":"{}","severity":"{}","component":)", e.seq,
                                to_string(e.kind), to_string(e.severity));
  exporter::append_json_string(out, e.component);
  out +=
      fmt::format(R"(,"component_id":{},"cycle":{},"fault_ns":{},"detected_ns":{},"latency_ns":{},)"
                  R"("count":{},"latched":{},"traced":{},"detail":)",
                  e.component_id, e.cycle, e.fault_ns, e.detected_ns, e.latency_ns(), e.count,
                  e.latched, e.traced);
  exporter::append_json_string(out, e.detail);
  // The process of an event about another process (`vigil supervise`); absent for this one's.
  if (e.pid != 0) out += fmt::format(R"(,"pid":{})", e.pid);
  out += '}';
  return out;
}

std::string trace_event_json(const supervisor::FlightRecord& r) {
  const int pid = static_cast<int>(r.component_id) + 1;
  const Track t{pid, r.has_info && r.info.tid != 0 ? r.info.tid : pid};
  exporter::JsonWriter w;
  w.begin_object();
  w.field("displayTimeUnit", "ms");
  w.key("traceEvents").begin_array();
  write_names(w, r, t);
  const supervisor::CycleRecord* prev = nullptr;
  for (const supervisor::CycleRecord& c : r.cycles) {
    write_cycle(w, c, prev, t);
    prev = &c;
  }
  write_health(w, r, t);
  if (!r.on_demand) write_fault(w, r, t);
  w.end_array();
  w.key("otherData");
  write_other_data(w, r);
  w.end_object();
  return w.take();
}

expected<void, Error> write_file_atomically(const std::filesystem::path& path,
                                            const std::string& text) {
  const std::filesystem::path tmp = path.string() + ".tmp";
  errno = 0;
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) {
    return vigil::unexpected(Error(errno, fmt::format("cannot write {}: {}", tmp.string(),
                                                      std::strerror(errno != 0 ? errno : EIO))));
  }
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && std::fflush(f) == 0;
  int err = ok ? 0 : errno;
  if (std::fclose(f) != 0 && ok) {
    ok = false;
    err = errno;
  }
  if (!ok) {
    std::filesystem::remove(tmp);
    return vigil::unexpected(Error(err, fmt::format("cannot write {}: {}", tmp.string(),
                                                    std::strerror(err != 0 ? err : EIO))));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    return vigil::unexpected(Error(
        ec.value(),
        fmt::format("cannot rename {} to {}: {}", tmp.string(), path.string(), ec.message())));
  }
  return {};
}

// --- TraceWriter ---

TraceWriter::TraceWriter(supervisor::ComponentAggregator& aggregator, TraceWriterOptions options)
    : aggregator_(aggregator), options_(std::move(options)) {}

expected<std::unique_ptr<TraceWriter>, Error> TraceWriter::start(
    supervisor::ComponentAggregator& aggregator, TraceWriterOptions options) {
  std::error_code ec;
  std::filesystem::create_directories(options.directory, ec);
  if (ec || !std::filesystem::is_directory(options.directory)) {
    return vigil::unexpected(
        Error(ec.value(), fmt::format("trace directory {}: {}", options.directory.string(),
                                      ec ? ec.message() : std::string("not a directory"))));
  }
  std::unique_ptr<TraceWriter> w(new TraceWriter(aggregator, std::move(options)));
  w->subscription_ =
      aggregator.events().subscribe([raw = w.get()](const Event& e) { raw->on_event(e); });
  return w;
}

TraceWriter::~TraceWriter() { aggregator_.events().unsubscribe(subscription_); }

void TraceWriter::on_event(const Event& e) {
  if (!e.traced) return;
  const auto record = aggregator_.frozen_record(e.seq);
  if (!record) {
    std::lock_guard lock(mutex_);
    error_ =
        fmt::format("the flight record of event {} ({}) is no longer kept", e.seq, e.component);
    return;
  }
  (void)write(*record, fmt::format("{}-{}", file_stem(e.component), e.seq));
}

expected<std::filesystem::path, Error> TraceWriter::write(const supervisor::FlightRecord& r,
                                                          const std::string& stem) {
  const std::filesystem::path path = options_.directory / (stem + ".trace.json");
  auto ok = write_file_atomically(path, trace_event_json(r) + "\n");
  std::lock_guard lock(mutex_);
  if (!ok) {
    error_ = ok.error().message;
    if (options_.log) options_.log("trace: " + error_);
    return vigil::unexpected(ok.error());
  }
  written_.push_back(path);
  if (options_.log) {
    options_.log(fmt::format("trace of {} ({} cycles, {}) written to {}", r.component,
                             r.cycles.size(), r.on_demand ? "on demand" : to_string(r.event.kind),
                             path.string()));
  }
  return path;
}

expected<std::filesystem::path, Error> TraceWriter::write_now(std::string_view name) {
  auto r = aggregator_.flight_record(name);
  if (!r) return vigil::unexpected(Error(fmt::format("no component named '{}'", name)));
  std::uint64_t n = 0;
  {
    std::lock_guard lock(mutex_);
    n = ++demands_;
  }
  return write(*r, fmt::format("{}-demand-{}", file_stem(name), n));
}

bool TraceWriter::flush(Nanos timeout_ns) { return aggregator_.events().flush(timeout_ns); }

std::vector<std::filesystem::path> TraceWriter::written() const {
  std::lock_guard lock(mutex_);
  return written_;
}

std::string TraceWriter::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

// --- EventLogWriter ---

EventLogWriter::EventLogWriter(supervisor::EventHub& hub, std::FILE* file,
                               std::filesystem::path path)
    : hub_(hub), file_(file), path_(std::move(path)) {}

expected<std::unique_ptr<EventLogWriter>, Error> EventLogWriter::start(
    supervisor::EventHub& hub, const std::filesystem::path& path) {
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    const int err = errno != 0 ? errno : EIO;
    return vigil::unexpected(Error(
        err, fmt::format("cannot write events to {}: {}", path.string(), std::strerror(err))));
  }
  std::unique_ptr<EventLogWriter> w(new EventLogWriter(hub, f, path));
  w->subscription_ = hub.subscribe([raw = w.get()](const Event& e) {
    const std::string line = event_json(e) + "\n";
    std::lock_guard lock(raw->mutex_);
    const bool ok = std::fwrite(line.data(), 1, line.size(), raw->file_) == line.size() &&
                    std::fflush(raw->file_) == 0;
    if (ok) {
      ++raw->written_;
    } else if (raw->error_.empty()) {
      raw->error_ = fmt::format("cannot write events to {}: {}", raw->path_.string(),
                                std::strerror(errno != 0 ? errno : EIO));
    }
  });
  return w;
}

EventLogWriter::~EventLogWriter() {
  hub_.unsubscribe(subscription_);
  std::fclose(file_);
}

std::uint64_t EventLogWriter::written() const {
  std::lock_guard lock(mutex_);
  return written_;
}

std::uint64_t EventLogWriter::lost() const { return hub_.stats(subscription_).lost; }

std::string EventLogWriter::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

}  // namespace vigil::exporter
