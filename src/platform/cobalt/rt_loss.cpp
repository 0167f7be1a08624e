// Cobalt real-time-loss detection: PTHREAD_WARNSW + a SIGDEBUG handler (XENOMAI.md §1).
//
// Design: the Cobalt core sends SIGDEBUG (= SIGXCPU) to a thread that set PTHREAD_WARNSW, on that
// thread, when it relaxes to secondary mode or hits another condition the core reports. One
// handler per process counts each notification by reason in process-wide lock-free counters and,
// for the reasons that are mode switches, in the thread's own initial-exec TLS counter, which
// supervision reads before and after each update. The handler runs on the offending thread,
// already in secondary mode; it only does async-signal-safe work (atomic increments, sigaction,
// raise), never I/O or allocation.
//
// The handler replaces libcobalt's (installed when libcobalt starts, initialize()), saved at
// install time. It chains to the saved one for NOMLOCK and WATCHDOG, where libcobalt reports and
// ends the process, as Xenomai intends. It does not chain for relaxes and debug reports:
// libcobalt's handler would restore the default action of SIGXCPU and re-raise, i.e. kill the
// process, while vigil's job is to count and report. Unmarked SIGXCPU (libcobalt's mode check of
// malloc/free in primary mode, RLIMIT_CPU, kill) is counted and ignored, as XENOMAI.md §1.3
// sketches.
#include "vigil/platform/rt_loss.hpp"

#include "platform/cobalt/build_check.hpp"
#include "platform/cobalt/core.hpp"

#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdint>

// Xenomai headers last: they define macros C++ headers must not see. <signal.h> and <pthread.h>
// above come from libcobalt's include directory and define SIGDEBUG, sigdebug_*() and
// pthread_setmode_np(); this one makes the dependency explicit.
#include <cobalt/uapi/signal.h>

namespace vigil::platform {

namespace {

static_assert(std::atomic<std::uint64_t>::is_always_lock_free,
              "SIGDEBUG counters must be lock-free to be updated from a signal handler");

// One counter per reason code the core defines (0..9, cobalt/uapi/signal.h); larger codes
// (a newer core) land in the last slot.
constexpr int kReasonSlots = 11;
constexpr int kUnknownSlot = kReasonSlots - 1;
static_assert(SIGDEBUG_MUTEX_SLEEP < kUnknownSlot, "a reason code has no counter of its own");
constinit std::atomic<std::uint64_t> g_reasons[kReasonSlots] = {};
constinit std::atomic<std::uint64_t> g_unmarked{0};

// The action that was installed before ours (normally libcobalt's cobalt_sigdebug_handler).
// Written once, before our handler can run; only read afterwards.
struct sigaction g_previous = {};

void count(int slot) noexcept { g_reasons[slot].fetch_add(1, std::memory_order_relaxed); }

std::uint64_t read(int slot) noexcept { return g_reasons[slot].load(std::memory_order_relaxed); }

void chain(int sig, siginfo_t* si, void* ctx) noexcept {
  if (g_previous.sa_handler == SIG_IGN) return;
  if (g_previous.sa_handler == SIG_DFL) {
    // Default action of SIGXCPU: terminate with a core dump. The signal is blocked while this
    // handler runs, so the re-raised one is delivered, with the default action, when it returns.
    sigaction(sig, &g_previous, nullptr);
    raise(sig);
    return;
  }
  if ((g_previous.sa_flags & SA_SIGINFO) != 0) {
    g_previous.sa_sigaction(sig, si, ctx);
  } else {
    g_previous.sa_handler(sig);
  }
}

void on_sigdebug(int sig, siginfo_t* si, void* ctx) {
  const int saved_errno = errno;
  if (si == nullptr || !sigdebug_marked(si)) {
    g_unmarked.fetch_add(1, std::memory_order_relaxed);
    errno = saved_errno;
    return;
  }
  const int reason = sigdebug_reason(si);
  count(reason < kUnknownSlot ? reason : kUnknownSlot);
  switch (reason) {
    case SIGDEBUG_MIGRATE_SIGNAL:
    case SIGDEBUG_MIGRATE_SYSCALL:
    case SIGDEBUG_MIGRATE_FAULT:
      ++detail::tls_mode_switches;
      break;
    case SIGDEBUG_WATCHDOG:
      // The core kicked a runaway thread out of primary mode: a (forced) mode switch, and
      // libcobalt's verdict follows.
      ++detail::tls_mode_switches;
      chain(sig, si, ctx);
      break;
    case SIGDEBUG_NOMLOCK:
      chain(sig, si, ctx);
      break;
    default:
      // MIGRATE_PRIOINV: a priority-inversion warning (this thread sleeps on a Cobalt mutex whose
      // owner runs in secondary mode), kept apart from the switches as XENOMAI.md §1.2 advises;
      // the debug reasons are reports. Counted per reason above, nothing more.
      break;
  }
  errno = saved_errno;
}

bool install_handler() noexcept {
  struct sigaction sa = {};
  sa.sa_sigaction = &on_sigdebug;
  sigemptyset(&sa.sa_mask);
  // SA_RESTART: a system call interrupted by the notification is resumed, not failed with EINTR.
  sa.sa_flags = SA_SIGINFO | SA_RESTART;
  // Save the current action first, so that it is in place before our handler can run.
  if (sigaction(SIGDEBUG, nullptr, &g_previous) != 0) return false;
  return sigaction(SIGDEBUG, &sa, nullptr) == 0;
}

}  // namespace

ThreadUsage thread_usage() noexcept {
  // getrusage() is a Linux system call: it would relax a primary-mode thread on every cycle, the
  // very thing the detectors look for. On Cobalt the blocking and page-fault detectors are
  // replaced by the mode-switch detector (a blocking Linux call or a page fault in primary mode
  // is a relax, reported by SIGDEBUG with its reason), so the usage counters read 0.
  return {};
}

bool arm_mode_switch_detection() noexcept {
  // No Cobalt thread exists before libcobalt starts (initialize()), and libcobalt installs its own
  // SIGDEBUG handler when it starts: ours must come after it (it saves libcobalt's to chain to).
  if (!detail::cobalt_ready()) return false;
  // Once per process: a function-local static is initialised exactly once even when several
  // threads arm at the same time (the others block until it is done; this is not RT code).
  static const bool installed = install_handler();
  if (!installed) return false;
  // The calling thread only. Returns a positive error number: EPERM when the caller is not a
  // Cobalt thread (std::thread, ...), which then cannot be armed. The call leaves the thread in
  // primary mode.
  return pthread_setmode_np(0, PTHREAD_WARNSW, nullptr) == 0;
}

ModeSwitchReasons mode_switch_reasons() noexcept {
  ModeSwitchReasons r;
  r.signal = read(SIGDEBUG_MIGRATE_SIGNAL);
  r.syscall = read(SIGDEBUG_MIGRATE_SYSCALL);
  r.fault = read(SIGDEBUG_MIGRATE_FAULT);
  r.watchdog = read(SIGDEBUG_WATCHDOG);
  r.priority_inversion = read(SIGDEBUG_MIGRATE_PRIOINV);
  r.no_mlock = read(SIGDEBUG_NOMLOCK);
  r.other = read(SIGDEBUG_UNDEFINED) + read(SIGDEBUG_RESCNT_IMBALANCE) + read(SIGDEBUG_LOCK_BREAK) +
            read(SIGDEBUG_MUTEX_SLEEP) + read(kUnknownSlot);
  r.unmarked = g_unmarked.load(std::memory_order_relaxed);
  return r;
}

}  // namespace vigil::platform
