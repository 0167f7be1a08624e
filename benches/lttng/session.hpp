#pragma once
/// @file
/// An LTTng tracing session for one benchmark process, driven through the `lttng` command line
/// (lttng-tools), as a user would: a session daemon is started if none runs
/// (`lttng-sessiond --daemonize --no-kernel`), then `lttng create` (output in a temporary
/// directory), `lttng enable-event --userspace 'vigil_bench:*'`, `lttng start`; `end()` runs
/// `lttng stop` and `lttng destroy` (each bounded to 60 s), removes the trace, and stops the
/// daemon if it started it, waiting until it has exited so that the next benchmark process does
/// not find a dying daemon. Every step that fails leaves the session unusable with a message saying
/// which step and why, for the benchmark to skip its row with.

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>

namespace vigil::bench {

class LttngSession {
 public:
  LttngSession() = default;
  LttngSession(const LttngSession&) = delete;
  LttngSession& operator=(const LttngSession&) = delete;
  ~LttngSession() { end(); }

  /// Starts the session; `enabled()` must become true once the session daemon has enabled this
  /// process's tracepoints (it is polled for up to 10 s). Returns false with `why()` set.
  bool begin(const std::function<bool()>& enabled) {
    if (run("lttng --version").rc != 0) return fail("lttng (lttng-tools) is not installed");
    if (run("lttng list").rc != 0) {
      const Result r = run("lttng-sessiond --daemonize --no-kernel");
      if (r.rc != 0) return fail("no session daemon runs and lttng-sessiond failed: " + r.out);
      started_daemon_ = true;
      daemon_pid_ = read_daemon_pid();
    }
    char dir[] = "/tmp/vigil-bench-lttng-XXXXXX";
    if (mkdtemp(dir) == nullptr) return fail("cannot create a temporary directory for the trace");
    dir_ = dir;
    name_ = "vigil-bench-" + std::to_string(getpid());
    const Result c = run("lttng create " + name_ + " --output=" + dir_);
    if (c.rc != 0) return fail("lttng create failed: " + c.out);
    created_ = true;
    const Result e = run("lttng enable-event --userspace --session=" + name_ + " 'vigil_bench:*'");
    if (e.rc != 0) return fail("lttng enable-event failed: " + e.out);
    const Result s = run("lttng start " + name_);
    if (s.rc != 0) return fail("lttng start failed: " + s.out);
    // The daemon enables the tracepoints in this process asynchronously (its registration
    // thread), which may also first have to find a daemon that started after this process.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!enabled()) {
      if (std::chrono::steady_clock::now() > deadline) {
        return fail(
            "the session started but did not enable this process's tracepoints within "
            "10 s");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    active_ = true;
    return true;
  }

  /// Stops and destroys the session, removes the trace, stops the daemon if begin() started it.
  /// Returns what `lttng stop` said (it warns there when events were discarded). Idempotent.
  std::string end() {
    std::string said;
    if (created_) {
      // Bounded: `lttng destroy` once did not return (23 minutes, on a daemon this process had
      // started); a benchmark must end.
      said = run("timeout 60 lttng stop " + name_).out;
      (void)run("timeout 60 lttng destroy " + name_);
      created_ = false;
    }
    active_ = false;
    if (!dir_.empty()) {
      std::error_code ec;
      std::filesystem::remove_all(dir_, ec);
      dir_.clear();
    }
    if (started_daemon_ && daemon_pid_ > 0 && kill(daemon_pid_, SIGTERM) == 0) {
      // Wait (up to 10 s) until it is gone, so that a benchmark started right after does not
      // find it still shutting down and make its session there.
      for (int i = 0; i < 500 && alive(daemon_pid_); ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    started_daemon_ = false;
    return said;
  }

  [[nodiscard]] bool active() const noexcept { return active_; }
  [[nodiscard]] const std::string& why() const noexcept { return why_; }
  /// One line for the benchmark's context.
  [[nodiscard]] std::string describe() const {
    if (!active_) return "not available: " + why_;
    return "session " + name_ + " (userspace, vigil_bench:*)" +
           (started_daemon_ ? ", session daemon started for it" : ", existing session daemon");
  }

 private:
  struct Result {
    int rc = -1;
    std::string out;
  };

  static Result run(const std::string& command) {
    Result r;
    FILE* p = popen((command + " 2>&1").c_str(), "r");
    if (p == nullptr) return r;
    std::array<char, 512> buf{};
    while (std::fgets(buf.data(), static_cast<int>(buf.size()), p) != nullptr) r.out += buf.data();
    const int status = pclose(p);
    r.rc = status == -1 ? -1 : WEXITSTATUS(status);
    while (!r.out.empty() && (r.out.back() == '\n' || r.out.back() == ' ')) r.out.pop_back();
    for (char& ch : r.out) {
      if (ch == '\n') ch = ' ';
    }
    return r;
  }

  /// Whether `pid` runs (a zombie does not: where init does not reap, it stays one).
  static bool alive(pid_t pid) {
    std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    if (!std::getline(f, line)) return false;
    const auto paren = line.rfind(')');
    return paren != std::string::npos && paren + 2 < line.size() && line[paren + 2] != 'Z';
  }

  /// The daemon's pid file: /var/run/lttng for root, $LTTNG_HOME or $HOME/.lttng otherwise.
  static pid_t read_daemon_pid() {
    std::string path;
    if (geteuid() == 0) {
      path = "/var/run/lttng/lttng-sessiond.pid";
    } else {
      const char* home = std::getenv("LTTNG_HOME");
      if (home == nullptr) home = std::getenv("HOME");
      if (home == nullptr) return 0;
      path = std::string(home) + "/.lttng/lttng-sessiond.pid";
    }
    for (int i = 0; i < 50; ++i) {
      std::ifstream f(path);
      long pid = 0;
      if (f >> pid && pid > 0) return static_cast<pid_t>(pid);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return 0;
  }

  bool fail(std::string why) {
    why_ = std::move(why);
    end();
    return false;
  }

  std::string name_;
  std::string dir_;
  std::string why_ = "not started";
  bool created_ = false;
  bool active_ = false;
  bool started_daemon_ = false;
  pid_t daemon_pid_ = 0;
};

}  // namespace vigil::bench
