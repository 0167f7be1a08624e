// CAN benchmarks.
//
// can/candump_parse: vigil's CandumpReader reading every frame of a candump log (open +
// read + parse, from the page cache), next to can-utils' log2asc converting the same file to
// /dev/null, timed in the same iteration (order alternating). The peer is timed from spawn to
// exit (posix_spawn + wait4): that includes its process start (~1 ms), which is what a user
// running it pays. Value = lines/s of vigil; floor = lines/s of log2asc (medians over the
// iterations); ratio = how many times faster vigil is, median of per-iteration ratios (goal >= 3).
//
// The capture: VIGIL_BENCH_CAN_LOG when set (a real `candump -l` log), otherwise one generated at
// start into a temporary file (can/synthetic_log.hpp: 90 s of a J1939 bus, ~36,000 frames,
// periodic groups with jitter and drift, requests and transport sessions), removed at exit; the
// context line "vigil.can_log" says which. log2asc is VIGIL_BENCH_LOG2ASC or the one found at
// configure time; without it the comparison row is "not available".
//
// can/sniffer_per_frame and can/supervisor: see their comments below (they report themselves
// unavailable when include/vigil/can/sniffer.hpp does not exist).
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "can/synthetic_log.hpp"
#include "support/bench_support.hpp"
#include "vigil/can/log/candump.hpp"
#if __has_include("vigil/can/sniffer.hpp")
#include "vigil/can/can_statistics.hpp"
#include "vigil/can/filter.hpp"
#include "vigil/can/protocol.hpp"
#include "vigil/can/sniffer.hpp"
#include "vigil/supervisor/drain_loop.hpp"
#endif

extern char** environ;

namespace vigil::bench {
namespace {

std::string env_or(const char* var, const char* fallback) {
  const char* v = std::getenv(var);
  return v != nullptr && *v != '\0' ? std::string(v) : std::string(fallback);
}

/// The capture every CAN benchmark reads: VIGIL_BENCH_CAN_LOG, or a generated one.
class CanLogSource {
 public:
  CanLogSource() {
    if (const char* v = std::getenv("VIGIL_BENCH_CAN_LOG"); v != nullptr && *v != '\0') {
      path_ = v;
      if (!std::ifstream(path_).good()) {
        problem_ = "not available: VIGIL_BENCH_CAN_LOG=" + path_ + " cannot be read";
      }
      description_ = "VIGIL_BENCH_CAN_LOG=" + path_;
      return;
    }
    char name[] = "/tmp/vigil-bench-can-XXXXXX.log";
    const int fd = mkstemps(name, 4);
    if (fd < 0) {
      problem_ = "not available: cannot create a temporary file for the generated capture";
      return;
    }
    ::close(fd);
    path_ = name;
    generated_ = true;
    const SyntheticCanLog log = write_synthetic_j1939_log(path_);
    if (log.frames == 0) {
      problem_ = "not available: cannot write the generated capture to " + path_;
      return;
    }
    description_ = "generated (benches/can/synthetic_log.hpp): " + std::to_string(log.frames) +
                   " frames, " + std::to_string(log.ids) + " ids, " +
                   std::to_string(static_cast<int>(log.seconds)) +
                   " s of a J1939 bus; set VIGIL_BENCH_CAN_LOG for a real capture";
  }
  ~CanLogSource() {
    if (generated_) std::remove(path_.c_str());
  }
  CanLogSource(const CanLogSource&) = delete;
  CanLogSource& operator=(const CanLogSource&) = delete;

  [[nodiscard]] const std::string& path() const { return path_; }
  /// Empty when the capture can be read; else the reason, for SkipWithError.
  [[nodiscard]] const std::string& problem() const { return problem_; }
  [[nodiscard]] const std::string& description() const { return description_; }

 private:
  std::string path_;
  std::string problem_;
  std::string description_;
  bool generated_ = false;
};

const CanLogSource& can_log() {
  static const CanLogSource source;
  return source;
}

std::string log_path() { return can_log().path(); }

std::string log2asc_path() {
#ifdef VIGIL_BENCH_LOG2ASC
  return env_or("VIGIL_BENCH_LOG2ASC", VIGIL_BENCH_LOG2ASC);
#else
  return env_or("VIGIL_BENCH_LOG2ASC", "");
#endif
}

std::size_t count_lines(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::size_t n = 0;
  std::string line;
  while (std::getline(in, line)) ++n;
  return n;
}

/// Reads every frame; returns the number of frames, or -1 on failure.
long parse_with_vigil(const std::string& path) {
  auto reader = can::CandumpReader::open(path);
  if (!reader) return -1;
  long frames = 0;
  for (;;) {
    auto entry = reader->next();
    if (!entry) return -1;
    if (!*entry) break;
    benchmark::DoNotOptimize(**entry);
    ++frames;
  }
  return frames;
}

/// Runs `log2asc -I path -O /dev/null <ifaces>`; returns its wall time in ns, or -1.
Nanos run_log2asc(const std::string& exe, const std::string& path,
                  const std::vector<std::string>& ifaces) {
  std::vector<std::string> args{exe, "-I", path, "-O", "/dev/null"};
  args.insert(args.end(), ifaces.begin(), ifaces.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const Nanos t0 = platform::now_ns();
  pid_t pid = 0;
  if (posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv.data(), environ) != 0) return -1;
  int status = 0;
  rusage ru{};
  if (wait4(pid, &status, 0, &ru) != pid) return -1;
  const Nanos t1 = platform::now_ns();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  return t1 - t0;
}

void candump_parse(benchmark::State& state) {
  const std::string path = log_path();
  const std::string exe = log2asc_path();
  if (!can_log().problem().empty()) {
    state.SkipWithError(can_log().problem().c_str());
    return;
  }
  if (exe.empty()) {
    state.SkipWithError(
        "not available: log2asc is not installed (can-utils; or set VIGIL_BENCH_LOG2ASC)");
    return;
  }
  const double lines = static_cast<double>(count_lines(path));
  // log2asc converts only the interfaces named on its command line: name every one of the log.
  std::vector<std::string> ifaces;
  if (auto log = can::read_candump_file(path)) ifaces = log->interfaces;
  if (parse_with_vigil(path) < 0 || run_log2asc(exe, path, ifaces) < 0) {  // warm the page cache
    state.SkipWithError("parsing the log or running log2asc failed");
    return;
  }

  std::vector<double> ours;
  std::vector<double> theirs;
  std::vector<double> ratios;
  bool ours_first = true;
  for (auto _ : state) {
    Nanos a = 0;
    Nanos b = 0;
    auto time_ours = [&] {
      const Nanos t0 = platform::now_ns();
      benchmark::DoNotOptimize(parse_with_vigil(path));
      return platform::now_ns() - t0;
    };
    if (ours_first) {
      a = time_ours();
      b = run_log2asc(exe, path, ifaces);
    } else {
      b = run_log2asc(exe, path, ifaces);
      a = time_ours();
    }
    ours_first = !ours_first;
    if (b < 0) {
      state.SkipWithError("log2asc failed");
      return;
    }
    ours.push_back(static_cast<double>(a));
    theirs.push_back(static_cast<double>(b));
    ratios.push_back(static_cast<double>(b) / static_cast<double>(a));
    state.SetIterationTime(static_cast<double>(a) * 1e-9);
  }
  // Medians over the iterations (wall time: the peer is another process).
  report_vs(state, "lines/s", lines / (median(ours) * 1e-9), lines / (median(theirs) * 1e-9),
            median(ratios));
  state.counters["goal_ratio_min"] = 3.0;
  state.counters["lines"] = lines;
}

}  // namespace
}  // namespace vigil::bench

namespace vigil::bench {
namespace {

#if __has_include("vigil/can/sniffer.hpp")
// can/sniffer_per_frame: what a CAN I/O component pays per frame it reads. Subject: two clock
// reads around the (empty) driver call, then Sniffer::on_read (J1939 node map, a filter that
// evaluates bus, format and node range and accepts every frame of the capture, both exact count
// tables, one push of the FrameRecord). Floor: the same two clock reads around the same empty
// call and one push of the same CanMessage into a boost spsc_queue of the sniffer port's
// capacity. Frames cycle through the capture; batches of 200 (< the port's 1024), alternating
// with the floor, after each poll of a consumer popping both every 10 ms (as for Task).
// Value = median ns per frame; ratio = median of per-batch subject/floor (goal <= 1.5, with the
// filter; filter:0, no filter installed, shows what the filter's guard and evaluation cost).
constexpr int kCanBatch = 200;
constexpr std::size_t kSnifferCapacity = 1024;

std::vector<can::Frame> log_frames() {
  std::vector<can::Frame> frames;
  if (auto log = can::read_candump_file(log_path())) {
    for (const auto& e : log->entries) frames.push_back(e.frame);
  }
  return frames;
}

[[gnu::noinline]] void empty_read() noexcept { benchmark::ClobberMemory(); }

class CanFloor {
 public:
  explicit CanFloor(const std::vector<can::Frame>& frames) : frames_(frames) {}
  [[gnu::noinline]] void cycle() noexcept {
    const can::Frame& f = frames_[next_];
    next_ = next_ + 1 == frames_.size() ? 0 : next_ + 1;
    const Nanos t0 = platform::now_ns();
    empty_read();
    const Nanos t1 = platform::now_ns();
    can::FrameRecord r;
    r.time_ns = t1;
    r.io_ns = t1 - t0;
    r.id = f.id;
    (void)queue_.push(can::CanMessage{r});
  }
  std::size_t drain() {
    return queue_.consume_all([](const can::CanMessage& m) { benchmark::DoNotOptimize(&m); });
  }

 private:
  const std::vector<can::Frame>& frames_;
  std::size_t next_ = 0;
  boost::lockfree::spsc_queue<can::CanMessage, boost::lockfree::capacity<kSnifferCapacity>> queue_;
};

class SnifferSubject {
 public:
  SnifferSubject(const std::vector<can::Frame>& frames, bool filtered)
      : frames_(frames), sniffer_(registry_, "bench_bus", {.node_map = can::NodeMap::j1939()}) {
    if (filtered) {
      (void)sniffer_.set_filter(can::match::bus({0}) && can::match::extended() &&
                                can::match::node_range(0, 0xFD));
    }
    registry_.ports().collect(entries_);
    buffer_.resize(64);
  }
  [[gnu::noinline]] void cycle() noexcept {
    const can::Frame& f = frames_[next_];
    next_ = next_ + 1 == frames_.size() ? 0 : next_ + 1;
    const Nanos t0 = platform::now_ns();
    empty_read();
    const Nanos t1 = platform::now_ns();
    sniffer_.on_read(f, t0, t1);
  }
  std::size_t drain() {
    std::size_t n = 0;
    for (auto& e : entries_) {
      for (std::size_t k; (k = e->port->pop(buffer_.data(), buffer_.size())) > 0;) n += k;
    }
    return n;
  }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return sniffer_.totals().dropped; }
  [[nodiscard]] std::uint64_t accepted() const noexcept { return sniffer_.totals().accepted; }

 private:
  const std::vector<can::Frame>& frames_;
  std::size_t next_ = 0;
  can::CanRegistry registry_;
  can::Sniffer<kSnifferCapacity> sniffer_;
  std::vector<std::shared_ptr<bus::RegistryEntry<can::CanMessage>>> entries_;
  std::vector<can::CanMessage> buffer_;
};

// The sniffer's per-frame work plus, inline, what the CAN supervisor does per frame for the
// protocol decoders (vigil/can/protocol.hpp: bus load in three stuffing modes with the exact
// frame's CRC-15, error frames, CANopen): the cost the decoders would add to the I/O thread if
// they ran there. They do not: they run in CanAggregator::on, on the CAN supervisor's thread.
class DecodingSubject {
 public:
  explicit DecodingSubject(const std::vector<can::Frame>& frames)
      : frames_(frames), sniffer_(registry_, "bench_bus", {.node_map = can::NodeMap::j1939()}) {
    (void)sniffer_.set_filter(can::match::bus({0}) && can::match::extended() &&
                              can::match::node_range(0, 0xFD));
    can::ProtocolOptions o;
    o.all_buses.bitrate = 250000;
    tracker_.set_options(o);
    registry_.ports().collect(entries_);
    buffer_.resize(1);
  }
  [[gnu::noinline]] void cycle() noexcept {
    const can::Frame& f = frames_[next_];
    next_ = next_ + 1 == frames_.size() ? 0 : next_ + 1;
    const Nanos t0 = platform::now_ns();
    empty_read();
    const Nanos t1 = platform::now_ns();
    sniffer_.on_read(f, t0, t1);
    for (auto& e : entries_) {
      if (e->port->pop(buffer_.data(), 1) == 1) {
        tracker_.on(std::get<can::FrameRecord>(buffer_[0]), can::NodeMapKind::J1939);
      }
    }
  }
  std::size_t drain() { return 0; }

 private:
  const std::vector<can::Frame>& frames_;
  std::size_t next_ = 0;
  can::CanRegistry registry_;
  can::Sniffer<kSnifferCapacity> sniffer_;
  can::ProtocolTracker tracker_;
  std::vector<std::shared_ptr<bus::RegistryEntry<can::CanMessage>>> entries_;
  std::vector<can::CanMessage> buffer_;
};

template <class S>
Nanos run_can_batch(S& s) {
  const Nanos t0 = platform::now_ns();
  for (int i = 0; i < kCanBatch; ++i) s.cycle();
  return platform::now_ns() - t0;
}

void sniffer_per_frame(benchmark::State& state) {
  const bool filtered = state.range(0) != 0;
  const std::vector<can::Frame> frames = log_frames();
  if (frames.empty()) {
    state.SkipWithError(can_log().problem().empty() ? "not available: the capture has no frame"
                                                    : can_log().problem().c_str());
    return;
  }
  CanFloor floor(frames);
  SnifferSubject subject(frames, filtered);
  Poller poller({[&](task::Message*, std::size_t) { return floor.drain(); },
                 [&](task::Message*, std::size_t) { return subject.drain(); }});
  for (int i = 0; i < 3; ++i) {  // warm-up: every id and node of the log enters the tables
    poller.wait_next_poll();
    for (std::size_t k = 0; k < frames.size(); k += kCanBatch) {
      (void)run_can_batch(floor);
      (void)run_can_batch(subject);
      poller.wait_next_poll();
    }
  }
  const std::uint64_t dropped0 = subject.dropped();
  measure_pair(
      state, "ns/frame", kCanBatch, [&] { poller.wait_next_poll(); },
      [&] { return run_can_batch(floor); }, [&] { return run_can_batch(subject); });
  if (filtered) state.counters["goal_ratio_max"] = 1.5;
  state.counters["dropped_per_frame"] = static_cast<double>(subject.dropped() - dropped0) /
                                        (static_cast<double>(state.iterations()) * kCanBatch);
}

// can/sniffer_per_frame_decoders: the sniffer's per-frame work (as can/sniffer_per_frame/
// filter:1) plus the protocol decoders' per-frame work run inline (DecodingSubject). Same floor,
// same batches. Compare its ns/frame with can/sniffer_per_frame/filter:1 of the same run
// (issue 48: goal <= 1.1x if the decoders ran on the I/O thread; they run on the CAN
// supervisor's, so the I/O thread pays can/sniffer_per_frame/filter:1 only).
void sniffer_per_frame_decoders(benchmark::State& state) {
  const std::vector<can::Frame> frames = log_frames();
  if (frames.empty()) {
    state.SkipWithError(can_log().problem().empty() ? "not available: the capture has no frame"
                                                    : can_log().problem().c_str());
    return;
  }
  CanFloor floor(frames);
  DecodingSubject subject(frames);
  Poller poller({[&](task::Message*, std::size_t) { return floor.drain(); },
                 [&](task::Message*, std::size_t) { return subject.drain(); }});
  for (int i = 0; i < 3; ++i) {
    poller.wait_next_poll();
    for (std::size_t k = 0; k < frames.size(); k += kCanBatch) {
      (void)run_can_batch(floor);
      (void)run_can_batch(subject);
      poller.wait_next_poll();
    }
  }
  measure_pair(
      state, "ns/frame", kCanBatch, [&] { poller.wait_next_poll(); },
      [&] { return run_can_batch(floor); }, [&] { return run_can_batch(subject); });
}

// can/supervisor_frames_per_s: DrainLoop<CanMessage, CanAggregator>::step() draining
// `sniffers` ports pre-filled with `per_port` records each (sniffers fed from the log outside
// the timing). Value = frames / CPU time of step() (the CPU clock's cost subtracted), median
// over the iterations. No goal was set.
void can_supervisor(benchmark::State& state) {
  const std::vector<can::Frame> frames = log_frames();
  if (frames.empty()) {
    state.SkipWithError(can_log().problem().empty() ? "not available: the capture has no frame"
                                                    : can_log().problem().c_str());
    return;
  }
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto per_port = static_cast<std::size_t>(state.range(1));
  can::CanRegistry registry;
  std::vector<std::unique_ptr<can::Sniffer<kSnifferCapacity>>> sniffers;
  for (std::size_t i = 0; i < n; ++i) {
    sniffers.push_back(std::make_unique<can::Sniffer<kSnifferCapacity>>(
        registry, "bus" + std::to_string(i),
        can::SnifferOptions{.node_map = can::NodeMap::j1939()}));
  }
  can::CanAggregator aggregator(registry);
  can::CanDrainLoop supervisor(registry.ports(), aggregator);
  std::size_t next = 0;
  Nanos t = platform::now_ns();
  auto fill = [&] {
    for (std::size_t k = 0; k < per_port; ++k) {
      for (auto& s : sniffers) {
        const can::Frame& f = frames[next];
        next = next + 1 == frames.size() ? 0 : next + 1;
        t += 1'000;
        s->on_read(f, t - 500, t);
      }
    }
  };
  (void)supervisor.step();
  fill();
  (void)supervisor.step();
  const Nanos clock_cost = cpu_clock_cost();
  std::vector<double> rates;
  for (auto _ : state) {
    fill();
    const Nanos c0 = thread_cpu_ns();
    const Nanos t0 = platform::now_ns();
    const std::size_t visited = supervisor.step();
    const Nanos t1 = platform::now_ns();
    const Nanos c1 = thread_cpu_ns();
    const Nanos cpu = std::max<Nanos>(c1 - c0 - clock_cost, 1);
    rates.push_back(static_cast<double>(visited) / (static_cast<double>(cpu) * 1e-9));
    state.SetIterationTime(static_cast<double>(t1 - t0) * 1e-9);
  }
  const double per_second = median(rates);
  report(state, "frames/s", per_second);
  state.counters["ns_per_frame"] = 1e9 / per_second;
}
#else
constexpr const char* kSnifferMissing =
    "not available: include/vigil/can/sniffer.hpp does not exist yet";
void sniffer_per_frame(benchmark::State& state) {
  for (auto _ : state) {
  }
  state.SkipWithError(kSnifferMissing);
}
void can_supervisor(benchmark::State& state) {
  for (auto _ : state) {
  }
  state.SkipWithError(kSnifferMissing);
}
void sniffer_per_frame_decoders(benchmark::State& state) {
  for (auto _ : state) {
  }
  state.SkipWithError(kSnifferMissing);
}
#endif
}  // namespace
}  // namespace vigil::bench

BENCHMARK(vigil::bench::sniffer_per_frame)
    ->Name("can/sniffer_per_frame")
    ->ArgNames({"filter"})
    ->Arg(1)
    ->Arg(0)
    ->Iterations(50)
    ->UseManualTime()
    ->Unit(benchmark::kNanosecond);
BENCHMARK(vigil::bench::sniffer_per_frame_decoders)
    ->Name("can/sniffer_per_frame_decoders")
    ->ArgNames({"filter"})
    ->Arg(1)
    ->Iterations(50)
    ->UseManualTime()
    ->Unit(benchmark::kNanosecond);
BENCHMARK(vigil::bench::can_supervisor)
    ->Name("can/supervisor")
    ->ArgNames({"sniffers", "per_port"})
    ->ArgsProduct({{1, 4}, {1'000}})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

BENCHMARK(vigil::bench::candump_parse)
    ->Name("can/candump_parse_vs_log2asc")
    ->Iterations(20)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
  return vigil::bench::run_main(argc, argv, [] {
    benchmark::AddCustomContext("vigil.can_log", vigil::bench::can_log().problem().empty()
                                                     ? vigil::bench::can_log().description()
                                                     : vigil::bench::can_log().problem());
  });
}
