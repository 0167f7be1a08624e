#pragma once
/// @file
/// Knowing whether another process still runs, and how it ended, without being its parent; and
/// recording, from inside a process, how it ends.
///
/// Identity: a pid alone is reused by the system, so a process is named by its pid and its start
/// time (clock ticks since boot, /proc/<pid>/stat field 22); a pid whose start time differs is
/// another process.
///
/// Death: `ProcessWatch` holds a pidfd (pidfd_open, Linux >= 5.3) that becomes readable when the
/// process ends; a daemon polls all of them in one call and so learns of a death at once. How it
/// ended (exit code or signal) is known to the parent only (wait), except that Linux >= 6.15
/// gives it to any holder of a pidfd opened before the death (PIDFD_GET_INFO with
/// PIDFD_INFO_EXIT). Elsewhere the zombie's /proc/<pid>/stat exit_code is read if the parent has
/// not reaped it yet, and otherwise the cause is unknown: SIGKILL cannot be caught, so the
/// process cannot record it either (see `install_exit_recorder`). docs/design/multi-process.md.
///
/// None of this is RT-safe (set-up calls and the daemon's thread), except where noted.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::platform {

/// A process, named so that pid reuse cannot confuse it with another.
struct ProcessIdentity {
  std::int32_t pid = 0;
  std::uint64_t start_ticks = 0;  ///< /proc/<pid>/stat field 22 (clock ticks since boot)

  friend bool operator==(const ProcessIdentity&, const ProcessIdentity&) = default;
};

/// The calling process's id (getpid: one cheap system call). Async-signal-safe; not for the
/// real-time path.
[[nodiscard]] std::int32_t current_pid() noexcept;

/// The calling process's identity (read once, then cached).
[[nodiscard]] ProcessIdentity self_identity() noexcept;

/// The start time of process `pid` in clock ticks since boot; nullopt when there is no such
/// process (or it is not visible: another pid namespace).
[[nodiscard]] std::optional<std::uint64_t> process_start_ticks(std::int32_t pid) noexcept;

/// Whether process `id` runs: same pid and same start time, and not a zombie.
[[nodiscard]] bool process_alive(const ProcessIdentity& id) noexcept;

/// What a process is doing, from the state letter of /proc/<pid>/stat.
enum class RunState : std::uint8_t {
  Running,  ///< running or waiting (R, S, D, I, W, P): it is scheduled when it has work
  Stopped,  ///< stopped by a signal (T: SIGSTOP, SIGTSTP, SIGTTIN, SIGTTOU); SIGCONT resumes it
  Traced,   ///< stopped by a tracer (t: a debugger at a breakpoint)
  Zombie,   ///< ended, not reaped by its parent yet (Z)
  Gone,     ///< no such process (ended and reaped, or another process holds the pid)
};
/// "running", "stopped", "traced", "zombie", "gone".
[[nodiscard]] const char* to_string(RunState s) noexcept;
/// The run state of state letter `c` (field 3 of /proc/<pid>/stat): X and unknown letters are
/// Gone. Pure (for tests).
[[nodiscard]] RunState run_state_of(char c) noexcept;
/// The run state of process `id` (Gone when the pid now names another process). One read of
/// /proc/<pid>/stat: not for the real-time path.
[[nodiscard]] RunState process_run_state(const ProcessIdentity& id) noexcept;

/// The calling process's command line, arguments separated by spaces, at most `max` bytes.
[[nodiscard]] std::string self_command_line(std::size_t max = 1024);
/// The calling process's name as the kernel keeps it (comm, at most 15 characters).
[[nodiscard]] std::string self_process_name();

/// Wall-clock time (ns since the Unix epoch) at which a process with `start_ticks` started.
/// A value beyond the ticks since boot (a corrupt one: it may come from a segment header) gives
/// now.
[[nodiscard]] std::int64_t start_time_unix_ns(std::uint64_t start_ticks) noexcept;
/// The wall clock now (ns since the Unix epoch). RT-safe: yes (vDSO).
[[nodiscard]] std::int64_t unix_now_ns() noexcept;
/// "2025-06-01 12:34:56" (local time) for a wall-clock time in ns since the epoch.
[[nodiscard]] std::string format_unix_time(std::int64_t unix_ns);

/// How a process ended.
struct ExitStatus {
  enum class Kind : std::uint8_t {
    Exited,    ///< exit(code) or return from main
    Signaled,  ///< terminated by signal `code`
  };
  Kind kind = Kind::Exited;
  int code = 0;  ///< exit code, or signal number
  bool core_dumped = false;

  /// "exited with code 3", "killed by signal 9 (SIGKILL)", "killed by signal 11 (SIGSEGV),
  /// core dumped".
  [[nodiscard]] std::string describe() const;
  /// From a wait(2) status word.
  [[nodiscard]] static ExitStatus from_wait_status(int status) noexcept;

  friend bool operator==(const ExitStatus&, const ExitStatus&) = default;
};

/// "SIGKILL" for 9, "SIG42" for a signal without a name.
[[nodiscard]] std::string signal_name(int signal);

/// Watches one process that is not necessarily a child. Move-only.
class ProcessWatch {
 public:
  ProcessWatch() = default;
  ProcessWatch(ProcessWatch&& o) noexcept;
  ProcessWatch& operator=(ProcessWatch&& o) noexcept;
  ProcessWatch(const ProcessWatch&) = delete;
  ProcessWatch& operator=(const ProcessWatch&) = delete;
  ~ProcessWatch();

  /// Starts watching `id`. Fails (code ESRCH) when the process is already gone or its pid now
  /// belongs to another process. Where pidfd_open is unavailable (old kernels, seccomp) the watch
  /// still works by reading /proc (fd() is then -1 and exited() must be polled).
  static expected<ProcessWatch, Error> open(const ProcessIdentity& id);

  /// A descriptor that becomes readable when the process ends (for wait_readable()), or -1.
  [[nodiscard]] int fd() const noexcept { return fd_; }
  [[nodiscard]] const ProcessIdentity& identity() const noexcept { return id_; }

  /// True once the process has ended (no blocking).
  [[nodiscard]] bool exited() const noexcept;

  /// How it ended, if this can be known to a non-parent (see the file comment); nullopt while
  /// it runs or when the cause is unknown. `source` (optional) is set to where it came from:
  /// "pidfd" or "zombie".
  [[nodiscard]] std::optional<ExitStatus> exit_status(const char** source = nullptr) const;

 private:
  int fd_ = -1;
  ProcessIdentity id_;
};

/// Waits until one of the `n` descriptors in `fds` (entries of -1 are ignored) is readable, or the
/// monotonic clock reaches `deadline_ns`. Sets `readable[i]` for each. Returns how many are
/// readable (0 at the deadline), or -errno. EINTR is resumed until the deadline.
int wait_readable(const int* fds, std::size_t n, Nanos deadline_ns, bool* readable) noexcept;

/// A function called when the process ends; it must be async-signal-safe (store to memory only).
/// `kind`/`code` say how: exit code, or the signal about to terminate the process.
using ExitRecorder = void (*)(ExitStatus::Kind kind, int code) noexcept;

/// Calls `recorder` when the process exits normally (exit(), return from main: glibc's on_exit)
/// or is about to be terminated by a catchable signal whose action is still the default one
/// (SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS,
/// SIGPIPE, SIGALRM, SIGUSR1, SIGUSR2, SIGXCPU, SIGXFSZ): the handler calls the recorder, restores
/// the default action and raises the signal again, so the process still dies of it (core dump
/// included). Signals the program already handles or ignores are left alone. Cannot see SIGKILL,
/// _exit() or a crash on an exhausted stack. The first call installs; later calls do nothing.
void install_exit_recorder(ExitRecorder recorder) noexcept;

}  // namespace vigil::platform
