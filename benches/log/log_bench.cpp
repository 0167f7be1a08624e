// The cost of one log call on the real-time thread, next to its floor and two peers, all in the
// same repetition.
//
// Subjects, each logging two integers and a double ("x {} y {} v {:.3f}"):
//   vigil    VIGIL_LOG_INFO inside a supervised cycle: thread-local source, run-time level,
//            the record written in place, one push into a Port<Message, 256> (a Task's port).
//   floor    one SPSC push of the same record: the same fields written into a Message and
//            pushed into a Port of the same type and capacity, with nothing else (no level, no
//            thread-local lookup, no indirect call). What any record-based logger must do.
//   fmt      fmt::format_to_n into a 256-byte stack buffer: formatting on the caller's thread,
//            without any queue.
//   spdlog   spdlog's async logger (Debian's libspdlog-dev): formats on the caller's thread, then
//            a mutex-protected queue and a condition variable; one worker thread (pinned to the
//            consumer CPU, SCHED_OTHER) writing to a null sink; queue 8192, overflow policy
//            block.
//
// Method. The measuring thread is pinned (VIGIL_BENCH_CPU, default 1). A single call costs a few
// nanoseconds, less than a clock read, so calls are timed in batches of 32 between two reads of
// vigil's clock; the cost of the two reads (the median of empty batches) is subtracted, and the
// per-call time of a batch is the rest / 32. p50 and p99 are over the batches of a repetition
// (2,000 per subject), so p99 is that of a 32-call mean, not of one call. Subject and floor
// batches alternate, the order switching every batch; spdlog runs after them, in the same
// repetition, on its own (see spdlog_async_vs_vigil). Between batches, outside the timing, the
// ports are drained (so that no push fails) and, should spdlog's worker fall far behind, its
// queue is waited down (so that no timed call blocks on a full queue).
//
// Rows: value = the subject's p50 in ns per call, floor = the floor's (or, for spdlog, vigil's)
// p50 in the same repetition, ratio = value / floor (for spdlog: spdlog / vigil, "x faster");
// the p99s and their ratio are extra counters. Goals: vigil p50 <= 1.3 x the floor; spdlog at
// least 10 x slower than vigil.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/log/log.hpp"

#if VIGIL_BENCH_HAVE_SPDLOG
#include <spdlog/async.h>
#include <spdlog/async_logger.h>
#include <spdlog/sinks/null_sink.h>
#endif

namespace vigil::bench {
namespace {

constexpr int kCalls = 32;       // calls per timed batch
constexpr int kBatches = 2'000;  // batches per subject per repetition
constexpr int kWarmup = 200;     // batches before the timed ones
constexpr double kGoalFloorRatio = 1.3;
constexpr double kGoalSpdlogRatio = 10.0;
using LogPort = Port<task::Message, kDefaultPortCapacity>;

/// The floor's call site (a real one, so the record is the same as vigil's).
constexpr log::CallSite kFloorSite{log::Level::Info, "x {} y {} v {:.3f}", __FILE__, __LINE__,
                                   nullptr};

/// Drains a port (outside the timing).
void drain(LogPort& port) {
  std::array<task::Message, 64> buf;
  while (port.pop(buf.data(), buf.size()) == buf.size()) {
  }
}

/// The floor: write the record's fields into a Message and push it.
struct Floor {
  LogPort port;
  task::Message message{std::in_place_type<log::LogRecord>};
  log::LogRecord* record = std::get_if<log::LogRecord>(&message);
  std::uint64_t cycle = 1;
  Nanos time_ns = 1;

  [[gnu::noinline]] void call(int i, int j, double d) noexcept {
    log::LogRecord& r = *record;
    r.site = &kFloorSite;
    r.cycle = cycle;
    r.time_ns = time_ns;
    std::byte* p = r.payload.data();
    std::memcpy(p, &i, sizeof i);
    std::memcpy(p + 4, &j, sizeof j);
    std::memcpy(p + 8, &d, sizeof d);
    r.size = 16;
    (void)port.try_push(message);
  }
};

/// vigil's call, inside a cycle of its source.
struct Vigil {
  Vigil() { source.enter(1, platform::now_ns()); }
  ~Vigil() { source.leave(); }
  Vigil(const Vigil&) = delete;
  Vigil& operator=(const Vigil&) = delete;

  [[gnu::noinline]] static void call(int i, int j, double d) noexcept {
    VIGIL_LOG_INFO("x {} y {} v {:.3f}", i, j, d);
  }

  LogPort port;
  log::PortSource<task::Message, kDefaultPortCapacity> source{"bench_log", &port};
};

[[gnu::noinline]] void fmt_call(char* buf, int i, int j, double d) noexcept {
  const auto r = fmt::format_to_n(buf, 256, "x {} y {} v {:.3f}", i, j, d);
  *r.out = '\0';
  benchmark::DoNotOptimize(buf);
}

#if VIGIL_BENCH_HAVE_SPDLOG
struct Spdlog {
  Spdlog()
      : pool(
            std::make_shared<spdlog::details::thread_pool>(8192, 1, [this] { on_worker_start(); })),
        logger(std::make_shared<spdlog::async_logger>(
            "bench", std::make_shared<spdlog::sinks::null_sink_mt>(), pool,
            spdlog::async_overflow_policy::block)) {
    logger->set_level(spdlog::level::info);
    // The worker inherits this thread's CPU (and SCHED_FIFO with --fifo): let it run and move
    // to the consumer CPU before anything is timed, by sleeping rather than spinning.
    while (!started.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  /// The worker runs where a user's would: on another CPU, SCHED_OTHER (it is created by the
  /// measuring thread, whose SCHED_FIFO it would otherwise inherit with --fifo).
  void on_worker_start() {
    pin_to_cpu(consumer_cpu());
    sched_param p{};
    p.sched_priority = 0;
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &p);
    started.store(true);
  }
  [[gnu::noinline]] void call(int i, int j, double d) {
    logger->info("x {} y {} v {:.3f}", i, j, d);
  }
  /// Waits (spinning, untimed) while the worker is far behind, so that a timed call never
  /// blocks on a full queue. The worker usually keeps up: this rarely waits.
  void wait_room() const {
    while (pool->queue_size() > 1024) std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  std::atomic<bool> started{false};
  std::shared_ptr<spdlog::details::thread_pool> pool;
  std::shared_ptr<spdlog::async_logger> logger;
};
#endif

/// Median cost of two back-to-back clock reads (subtracted from every batch).
Nanos clock_pair_cost() {
  std::vector<double> d;
  for (int i = 0; i < 10'001; ++i) {
    const Nanos a = platform::now_ns();
    const Nanos b = platform::now_ns();
    d.push_back(static_cast<double>(b - a));
  }
  return static_cast<Nanos>(median(d));
}

/// ns per call of one batch of `f(i)`, the clock's own cost removed.
template <class F>
double batch(F&& f, Nanos clock_cost) {
  const Nanos t0 = platform::now_ns();
  for (int i = 0; i < kCalls; ++i) f(i);
  const Nanos t1 = platform::now_ns();
  return static_cast<double>(std::max<Nanos>(t1 - t0 - clock_cost, 0)) / kCalls;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(k, v.size() - 1)];
}

/// Runs `subject` and `reference` in alternating batches; `after` runs after each pair, untimed.
template <class S, class R, class A>
void alternate(std::vector<double>& s, std::vector<double>& r, S&& subject, R&& reference,
               A&& after, Nanos clock_cost) {
  for (int b = -kWarmup; b < kBatches; ++b) {
    double ts = 0;
    double tr = 0;
    if ((b & 1) == 0) {
      ts = batch(subject, clock_cost);
      tr = batch(reference, clock_cost);
    } else {
      tr = batch(reference, clock_cost);
      ts = batch(subject, clock_cost);
    }
    after();
    if (b >= 0) {
      s.push_back(ts);
      r.push_back(tr);
    }
  }
}

void report_pair(benchmark::State& state, const std::vector<double>& s,
                 const std::vector<double>& r, bool peer_over_subject) {
  const double s50 = percentile(s, 0.5), s99 = percentile(s, 0.99);
  const double r50 = percentile(r, 0.5), r99 = percentile(r, 0.99);
  const auto ratio = [&](double a, double b) {
    if (peer_over_subject) std::swap(a, b);
    return b > 0 ? a / b : 0.0;
  };
  report_vs(state, "ns/call p50", peer_over_subject ? r50 : s50, peer_over_subject ? s50 : r50,
            ratio(s50, r50));
  state.counters["p99"] = peer_over_subject ? r99 : s99;
  state.counters["floor_p99"] = peer_over_subject ? s99 : r99;
  state.counters["ratio_p99"] = ratio(s99, r99);
}

void vigil_vs_floor(benchmark::State& state) {
  const Nanos cost = clock_pair_cost();
  Vigil v;
  Floor f;
  std::vector<double> sv, sf;
  int j = 0;
  for (auto _ : state) {
    sv.clear();
    sf.clear();
    alternate(
        sv, sf, [&](int i) { Vigil::call(i, j, i * 0.5); }, [&](int i) { f.call(i, j, i * 0.5); },
        [&] {
          ++j;
          drain(v.port);
          drain(f.port);
        },
        cost);
  }
  if (v.source.dropped() != 0 || f.port.dropped() != 0) state.SkipWithError("a push failed");
  report_pair(state, sv, sf, false);
  state.counters["goal_ratio_max"] = kGoalFloorRatio;
}

void fmt_vs_floor(benchmark::State& state) {
  const Nanos cost = clock_pair_cost();
  Floor f;
  std::array<char, 257> buf{};
  std::vector<double> sm, sf;
  int j = 0;
  for (auto _ : state) {
    sm.clear();
    sf.clear();
    alternate(
        sm, sf, [&](int i) { fmt_call(buf.data(), i, j, i * 0.5); },
        [&](int i) { f.call(i, j, i * 0.5); },
        [&] {
          ++j;
          drain(f.port);
        },
        cost);
  }
  report_pair(state, sm, sf, false);
}

void spdlog_async_vs_vigil(benchmark::State& state) {
#if VIGIL_BENCH_HAVE_SPDLOG
  const Nanos cost = clock_pair_cost();
  Spdlog s;  // first: its worker thread moves to the consumer CPU before the rest is built
  Vigil v;
  Floor f;
  std::vector<double> sv, sf, ss;
  int j = 0;
  for (auto _ : state) {
    sv.clear();
    sf.clear();
    ss.clear();
    // vigil against its floor, then spdlog on its own, in the same repetition. Not interleaved
    // with spdlog: each spdlog call takes a mutex and may wake the worker (a system call), which
    // would leave vigil's next batch running on cold caches and charge spdlog's cost to vigil.
    alternate(
        sv, sf, [&](int i) { Vigil::call(i, j, i * 0.5); }, [&](int i) { f.call(i, j, i * 0.5); },
        [&] {
          ++j;
          drain(v.port);
          drain(f.port);
        },
        cost);
    for (int b = -kWarmup; b < kBatches; ++b) {
      const double t = batch([&](int i) { s.call(i, j, i * 0.5); }, cost);
      ++j;
      s.wait_room();
      if (b >= 0) ss.push_back(t);
    }
  }
  // value: spdlog's p50; floor: vigil's (the peer comparison); ratio: spdlog / vigil.
  report_pair(state, sv, ss, true);
  state.counters["goal_ratio_min"] = kGoalSpdlogRatio;
  const double f50 = percentile(sf, 0.5);
  state.counters["spdlog_vs_floor"] = f50 > 0 ? percentile(ss, 0.5) / f50 : 0.0;
  state.counters["vigil_vs_floor"] = f50 > 0 ? percentile(sv, 0.5) / f50 : 0.0;
#else
  for (auto _ : state) {
  }
  state.SkipWithError("spdlog not found at configure time (Debian: libspdlog-dev)");
#endif
}

BENCHMARK(vigil_vs_floor)->Name("log/vigil_call_vs_floor")->Iterations(1)->UseRealTime();
BENCHMARK(fmt_vs_floor)->Name("log/fmt_format_to_vs_floor")->Iterations(1)->UseRealTime();
BENCHMARK(spdlog_async_vs_vigil)->Name("log/spdlog_async_vs_vigil")->Iterations(1)->UseRealTime();

}  // namespace
}  // namespace vigil::bench

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
