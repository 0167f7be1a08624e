#pragma once
/// @file
/// Real-time-loss probes: cheap per-thread counters read before and after a component's update.
///
/// A real-time loss is anything in an update that can block for an unbounded time. The probes
/// here return cumulative counts for the calling thread; supervision takes the difference
/// around `on_update()` and attributes it to the component.

#include <cstdint>

namespace vigil::platform {

/// Causes of real-time loss, counted separately.
enum class LossCause : std::uint8_t {
  Allocation,  ///< heap allocation (malloc family, operator new) on the thread
  Blocking,    ///< voluntary context switch: slept, waited on a lock, blocking I/O
  MinorFault,  ///< minor page fault (first touch of a page, copy on write)
  MajorFault,  ///< major page fault (page read from disk)
  ModeSwitch,  ///< Cobalt: switch to secondary mode (SIGDEBUG), by any reason
};
inline constexpr int kLossCauseCount = 5;

/// "allocation", "blocking", "minor_fault", "major_fault", "mode_switch".
[[nodiscard]] const char* to_string(LossCause c) noexcept;

/// Counters of the calling thread that the kernel keeps (getrusage(RUSAGE_THREAD)).
struct ThreadUsage {
  std::uint64_t voluntary_switches = 0;
  std::uint64_t involuntary_switches = 0;
  std::uint64_t minor_faults = 0;
  std::uint64_t major_faults = 0;
};

/// Reads the calling thread's usage counters. RT-safe: no allocation or lock, but one system
/// call (~300 ns): only used when a component opts into the blocking or page-fault detector.
/// On Cobalt this call would relax a primary-mode thread; there these detectors are replaced by
/// the mode-switch detector.
[[nodiscard]] ThreadUsage thread_usage() noexcept;

/// Number of heap allocations made so far by the calling thread, as counted by the
/// `vigil::alloc_guard` interposer. Always 0 when alloc_guard is not linked.
/// RT-safe: yes (one thread-local load, inlined).
[[nodiscard]] inline std::uint64_t thread_allocations() noexcept;

/// True when the vigil::alloc_guard interposer is linked into the program. RT-safe: yes.
[[nodiscard]] bool allocation_counting_available() noexcept;

/// Number of switches to secondary mode of the calling thread since
/// `arm_mode_switch_detection()` (Cobalt; always 0 on Linux). RT-safe: yes (thread-local load).
[[nodiscard]] inline std::uint64_t thread_mode_switches() noexcept;

/// Cobalt: sets PTHREAD_WARNSW on the calling thread and installs the SIGDEBUG handler once per
/// process (chaining the previous one). Linux: does nothing and returns false.
/// Call once from the real-time thread before its loop. Not RT-safe.
bool arm_mode_switch_detection() noexcept;

/// Process-wide counts of the SIGDEBUG notifications received by threads armed with
/// `arm_mode_switch_detection()`, by the reason the Cobalt core gave. All zero on Linux.
/// `thread_mode_switches()` counts, per thread, the reasons marked "mode switch" below.
struct ModeSwitchReasons {
  std::uint64_t signal = 0;    ///< mode switch: relaxed to handle a Linux signal
  std::uint64_t syscall = 0;   ///< mode switch: issued a regular Linux system call
  std::uint64_t fault = 0;     ///< mode switch: processor fault or exception (e.g. page fault)
  std::uint64_t watchdog = 0;  ///< mode switch forced by the Cobalt watchdog (runaway thread)
  /// Slept on a Cobalt mutex whose owner ran in secondary mode (priority inversion).
  std::uint64_t priority_inversion = 0;
  std::uint64_t no_mlock = 0;  ///< process memory was not locked (a configuration error)
  /// Debug reports (resource-count imbalance, lock break, sleeping while holding a mutex) and
  /// reasons this version of vigil does not know.
  std::uint64_t other = 0;
  /// SIGXCPU not sent by the Cobalt core: libcobalt's mode check (malloc/free called in primary
  /// mode while armed), RLIMIT_CPU, kill(2). Counted and otherwise ignored.
  std::uint64_t unmarked = 0;
};

/// Reads the per-reason counters. RT-safe: yes (relaxed atomic loads, no system call).
[[nodiscard]] ModeSwitchReasons mode_switch_reasons() noexcept;

}  // namespace vigil::platform

namespace vigil::platform::detail {
// Per-thread counters. constinit + initial-exec TLS: no TLS wrapper call and no lazy allocation,
// so they can be read on the real-time path and written from a signal handler.
/// Heap allocations of this thread, written by alloc_guard's interposer. Not API.
extern thread_local constinit std::uint64_t tls_allocations
    __attribute__((tls_model("initial-exec")));
/// Switches to secondary mode of this thread, written by the Cobalt SIGDEBUG handler. Not API.
extern thread_local constinit std::uint64_t tls_mode_switches
    __attribute__((tls_model("initial-exec")));
/// Set to true by alloc_guard's static initialiser. Not API.
extern bool alloc_guard_linked;
}  // namespace vigil::platform::detail

namespace vigil::platform {
inline std::uint64_t thread_allocations() noexcept { return detail::tls_allocations; }
inline std::uint64_t thread_mode_switches() noexcept { return detail::tls_mode_switches; }
}  // namespace vigil::platform
