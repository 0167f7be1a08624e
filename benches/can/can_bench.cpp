// CAN benchmarks.
//
// can/candump_parse: vigil's CandumpReader reading every frame of a real candump log (open +
// read + parse, from the page cache), next to can-utils' log2asc converting the same file to
// /dev/null, timed in the same iteration (order alternating). The peer is timed from spawn to
// exit (posix_spawn + wait4): that includes its process start (~1 ms), which is what a user
// running it pays. Value = lines/s of vigil; floor = lines/s of log2asc (medians over the
// iterations); ratio = how many times faster vigil is, median of per-iteration ratios (goal >= 3).
// The log is VIGIL_BENCH_CAN_LOG, or the shared capture
// ../shared/data/can/j1939_truck_candump-2022-03-29.log; log2asc is VIGIL_BENCH_LOG2ASC or the one
// found at configure time. Without either the benchmark reports an error
// ("not available" in benches/run).
//
// The sniffer and the CAN supervisor are measured here once include/vigil/can/sniffer.hpp
// exists (see the section at the end).
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "support/bench_support.hpp"
#include "vigil/can/candump.hpp"

extern char** environ;

namespace vigil::bench {
namespace {

std::string env_or(const char* var, const char* fallback) {
  const char* v = std::getenv(var);
  return v != nullptr && *v != '\0' ? std::string(v) : std::string(fallback);
}

std::string log_path() {
#ifdef VIGIL_BENCH_CAN_DATA
  return env_or("VIGIL_BENCH_CAN_LOG", VIGIL_BENCH_CAN_DATA);
#else
  return env_or("VIGIL_BENCH_CAN_LOG", "");
#endif
}

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
  if (path.empty() || !std::ifstream(path).good()) {
    state.SkipWithError("CAN log not found (set VIGIL_BENCH_CAN_LOG)");
    return;
  }
  if (exe.empty()) {
    state.SkipWithError("log2asc not found (install can-utils or set VIGIL_BENCH_LOG2ASC)");
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

BENCHMARK(vigil::bench::candump_parse)
    ->Name("can/candump_parse_vs_log2asc")
    ->Iterations(20)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) { return vigil::bench::run_main(argc, argv); }
