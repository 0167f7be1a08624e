#include "vigil/can/replay.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <variant>

#include "vigil/can/log/candump.hpp"
#include "vigil/can/log/trc.hpp"
#include "vigil/can/sniffer.hpp"

namespace vigil::can {

namespace {

// The replay clock: the latest log timestamp (the supervisor's own timing is meaningless in a
// replay, but it must not read the wall clock for it either).
Nanos replay_now(const void* ctx) noexcept { return *static_cast<const Nanos*>(ctx); }

}  // namespace

struct LogReplay::Impl {
  ReplayOptions options;
  CanRegistry registry;
  Sniffer<kPortCapacity> sniffer;
  CanAggregator aggregator;
  Nanos clock_ns = 0;
  CanDrainLoop supervisor;
  std::size_t pending = 0;
  std::uint64_t frames = 0;
  Nanos first = 0;
  Nanos last = 0;
  std::vector<ReplayFile> files;
  std::vector<std::string> bus_names;

  explicit Impl(ReplayOptions o)
      : options(std::move(o)),
        sniffer(registry, "replay",
                SnifferOptions{.max_ids = options.max_ids,
                               .max_nodes = options.max_nodes,
                               .node_map = options.node_map}),
        aggregator(registry, CanAggregatorOptions{.exact_percentiles = options.exact_percentiles,
                                                  .max_ids = options.max_ids,
                                                  .max_nodes = options.max_nodes,
                                                  .protocol = options.protocol}),
        supervisor(registry.ports(), aggregator,
                   supervisor::DrainOptions{.period_ns = 100 * kNanosPerMilli,
                                            .batch = 256,
                                            .thread_name = "vigil-can-replay",
                                            .clock = Clock{&replay_now, &clock_ns}}) {}

  void feed(const Frame& f, Direction d) {
    if (frames == 0) {
      first = f.timestamp;
      last = f.timestamp;
    }
    first = std::min(first, f.timestamp);
    last = std::max(last, f.timestamp);
    clock_ns = std::max(clock_ns, last);
    ++frames;
    sniffer.on_frame(f, d, f.timestamp, f.timestamp);
    // Each frame pushes at most one record: step before the port can be full, so that the
    // replay never drops a record.
    if (++pending >= kPortCapacity) flush();
  }

  void flush() {
    supervisor.step();
    pending = 0;
  }

  std::uint8_t bus_index(const std::string& name) {
    const auto it = std::find(bus_names.begin(), bus_names.end(), name);
    if (it != bus_names.end()) return static_cast<std::uint8_t>(it - bus_names.begin());
    bus_names.push_back(name);
    return static_cast<std::uint8_t>(bus_names.size() - 1);
  }
};

LogReplay::LogReplay(ReplayOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  if (!impl_->options.filter.accepts_all()) {
    // An invalid filter is the caller's error; it is reported by load_can_config / compile
    // before a replay is built, so a failure here keeps accept-all.
    static_cast<void>(impl_->sniffer.set_filter(impl_->options.filter));
  }
  impl_->flush();  // the supervisor picks up the sniffer
}

LogReplay::~LogReplay() = default;

void LogReplay::feed(const Frame& f, Direction d) { impl_->feed(f, d); }

void LogReplay::flush() { impl_->flush(); }

CanSnapshot LogReplay::snapshot(std::span<const GroupSpec> groups) {
  flush();
  return impl_->aggregator.snapshot(groups);
}

CanReport LogReplay::report(const CanMonitor& monitor) { return report(monitor, impl_->last); }

CanReport LogReplay::report(const CanMonitor& monitor, Nanos now) {
  // The log has been read up to `now` (the caller fed every frame before it): the supervisor's
  // cycle, and so the time silences are judged up to, is `now`.
  impl_->clock_ns = std::max(impl_->clock_ns, now);
  flush();
  CanReport r = monitor.evaluate(impl_->aggregator, now);
  std::uint64_t malformed = 0;
  for (const ReplayFile& f : impl_->files) malformed += f.malformed;
  if (impl_->frames == 0 && malformed > 0) {
    r.status.merge(StatusLevel::Warn,
                   fmt::format("no valid frame in the logs: {} malformed line{} skipped", malformed,
                               malformed == 1 ? "" : "s"));
  }
  return r;
}

std::uint64_t LogReplay::frames() const noexcept { return impl_->frames; }
Nanos LogReplay::first_ns() const noexcept { return impl_->first; }
Nanos LogReplay::last_ns() const noexcept { return impl_->last; }
const std::vector<ReplayFile>& LogReplay::files() const noexcept { return impl_->files; }
const std::vector<std::string>& LogReplay::bus_names() const noexcept { return impl_->bus_names; }
SnifferTotals LogReplay::totals() const noexcept { return impl_->sniffer.totals(); }
const CanAggregator& LogReplay::aggregator() const noexcept { return impl_->aggregator; }

LogFormat detect_log_format(const std::filesystem::path& path, LogFormat format) {
  if (format != LogFormat::Auto) return format;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".trc" ? LogFormat::Trc : LogFormat::Candump;
}

std::string_view to_string(LogFormat f) noexcept {
  switch (f) {
    case LogFormat::Auto:
      return "auto";
    case LogFormat::Candump:
      return "candump";
    case LogFormat::Trc:
      return "trc";
  }
  return "?";
}

namespace {

// One open log with its next frame (read ahead for the timestamp merge).
struct Source {
  std::variant<CandumpReader, TrcReader> reader;
  std::size_t file = 0;              // index in LogReplay's files()
  std::vector<std::uint8_t> bus_of;  // reader's bus index -> replay bus index
  LogEntry* next = nullptr;          // the reader's own entry (no copy), null at the end
};

expected<void, Error> advance(Source& s, LogReplay::Impl& m) {
  expected<LogEntry*, Error> e = std::visit([](auto& r) { return r.next_entry(); }, s.reader);
  if (!e) return unexpected(e.error());
  s.next = *e;
  if (s.next == nullptr) return {};
  Frame& f = s.next->frame;
  // Map the reader's bus index to the replay's.
  if (auto* c = std::get_if<CandumpReader>(&s.reader)) {
    const auto& names = c->interfaces();
    while (s.bus_of.size() < names.size()) s.bus_of.push_back(m.bus_index(names[s.bus_of.size()]));
  } else {
    while (s.bus_of.size() <= f.bus) {
      s.bus_of.push_back(m.bus_index(fmt::format("bus{}", s.bus_of.size() + 1)));
    }
  }
  f.bus = s.bus_of[f.bus];
  return {};
}

void finish_file(const Source& s, ReplayFile& rf) {
  std::visit(
      [&](const auto& r) {
        rf.malformed = r.malformed_count();
        rf.errors = r.errors();
        if constexpr (std::is_same_v<std::decay_t<decltype(r)>, TrcReader>) {
          rf.skipped = r.skipped_count();
        }
      },
      s.reader);
}

}  // namespace

expected<void, Error> LogReplay::feed_files(std::span<const std::filesystem::path> paths,
                                            LogFormat format) {
  Impl& m = *impl_;
  std::vector<Source> sources;
  sources.reserve(paths.size());
  for (const std::filesystem::path& p : paths) {
    ReplayFile rf;
    rf.path = p;
    rf.format = detect_log_format(p, format);
    m.files.push_back(rf);
    const std::size_t index = m.files.size() - 1;
    if (rf.format == LogFormat::Trc) {
      auto r = TrcReader::open(p, m.options.reader);
      if (!r) return unexpected(r.error());
      sources.push_back(Source{std::move(*r), index, {}, nullptr});
    } else {
      auto r = CandumpReader::open(p, m.options.reader);
      if (!r) return unexpected(r.error());
      sources.push_back(Source{std::move(*r), index, {}, nullptr});
    }
  }
  for (Source& s : sources) {
    if (auto r = advance(s, m); !r) return r;
  }
  for (;;) {
    // The source with the earliest next frame; ties go to the file given first.
    Source* best = nullptr;
    for (Source& s : sources) {
      if (s.next && (best == nullptr || s.next->frame.timestamp < best->next->frame.timestamp)) {
        best = &s;
      }
    }
    if (best == nullptr) break;
    const LogEntry& e = *best->next;
    m.feed(e.frame, e.direction.value_or(m.options.default_direction));
    ++m.files[best->file].frames;
    if (auto r = advance(*best, m); !r) {
      finish_file(*best, m.files[best->file]);
      return r;
    }
  }
  for (const Source& s : sources) finish_file(s, m.files[s.file]);
  m.flush();
  return {};
}

}  // namespace vigil::can
