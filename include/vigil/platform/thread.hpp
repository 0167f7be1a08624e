#pragma once
/// @file
/// Thread creation with name, scheduling policy, priority, CPU affinity and stack size.
///
/// All functions here are for set-up and tear-down, off the real-time path, unless a comment says
/// otherwise. On Cobalt, real-time threads must be created here (never with std::thread, which
/// bypasses libcobalt's wrappers, see docs/design/platform.md).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::platform {

/// Scheduling policy of a thread.
enum class SchedPolicy : std::uint8_t {
  Other,  ///< SCHED_OTHER: time-sharing, not real-time.
  Fifo,   ///< SCHED_FIFO: fixed-priority real-time (priority 1..99).
};

/// "OTHER" or "FIFO".
[[nodiscard]] const char* to_string(SchedPolicy p) noexcept;

/// Stack of the threads vigil creates for itself (supervisor, monitor, file watcher, the CAN
/// supervisor), unless their options say otherwise: 256 KiB. Their deepest use measured in the
/// demo is below 64 KiB (docs/design/memory.md). Under mlockall every byte of a thread's stack is
/// resident and locked, so the size of a stack is what the thread costs in RAM.
inline constexpr std::size_t kDefaultStackBytes = std::size_t{256} * 1024;

/// What a thread is created with.
struct ThreadConfig {
  /// Thread name (at most 15 characters are kept by Linux; longer names are truncated).
  std::string name = "vigil";
  /// Scheduling policy.
  SchedPolicy policy = SchedPolicy::Other;
  /// Priority: 1..99 for Fifo; ignored (0) for Other.
  int priority = 0;
  /// CPU to pin the thread to, or -1 for no affinity.
  int cpu = -1;
  /// Stack size in bytes (kDefaultStackBytes unless set). 0 keeps the system default, which on
  /// Linux is `ulimit -s` (usually 8 MiB) and is then entirely resident under mlockall. Raised to
  /// PTHREAD_STACK_MIN (16 KiB on x86-64) if smaller. A thread that needs more than its stack
  /// overflows into the guard page and the process gets SIGSEGV: size it for the deepest call.
  std::size_t stack_bytes = kDefaultStackBytes;
  /// Bytes of stack to touch at thread start so that the first cycles take no page fault; at
  /// most half of `stack_bytes` is touched (when `stack_bytes` is not 0).
  std::size_t prefault_stack_bytes = std::size_t{64} * 1024;
};

/// A joinable thread made by `Thread::spawn`. Move-only; joins in its destructor if still
/// joinable.
class Thread {
 public:
  Thread() noexcept;
  Thread(Thread&&) noexcept;
  Thread& operator=(Thread&&) noexcept;
  Thread(const Thread&) = delete;
  Thread& operator=(const Thread&) = delete;
  ~Thread();

  /// Creates a thread running `body` with exactly `config`'s policy, priority and CPU.
  ///
  /// Fails (never silently downgrades) when the system refuses the configuration, e.g. EPERM
  /// for SCHED_FIFO without CAP_SYS_NICE/RLIMIT_RTPRIO, EINVAL for a priority out of range or a
  /// CPU that does not exist. The caller decides whether to retry with SchedPolicy::Other and
  /// must report that it did. Not RT-safe (allocates, system calls).
  [[nodiscard]] static expected<Thread, Error> spawn(const ThreadConfig& config,
                                                     std::function<void()> body);

  /// Waits for the thread to finish. Not RT-safe. No-op if not joinable.
  void join() noexcept;
  [[nodiscard]] bool joinable() const noexcept;
  /// Kernel thread id (Linux TID) of the thread; valid once spawn() returned.
  [[nodiscard]] int tid() const noexcept;

  struct State;  ///< Implementation detail (defined by the platform implementation).

 private:
  std::unique_ptr<State> state_;
};

/// Kernel thread id of the calling thread. RT-safe: yes after the first call on a thread
/// (cached in thread-local storage; the first call makes one system call).
[[nodiscard]] int current_tid() noexcept;

/// Number of CPUs online. Not RT-safe.
[[nodiscard]] int cpu_count() noexcept;

/// Scheduling identity of a thread as the kernel reports it.
struct SchedInfo {
  SchedPolicy policy = SchedPolicy::Other;
  int priority = 0;
  /// CPU the thread is pinned to if its affinity mask has exactly one CPU, else -1.
  int pinned_cpu = -1;
};

/// Reads the calling thread's policy, priority and affinity. Not RT-safe (system calls).
[[nodiscard]] expected<SchedInfo, Error> current_sched_info();

}  // namespace vigil::platform
