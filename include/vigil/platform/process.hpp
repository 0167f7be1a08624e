#pragma once
/// @file
/// Small process-level services for programs built on vigil: the start of the platform's
/// real-time core, a terminal test and a clean stop on Ctrl-C / SIGTERM. None of these is
/// RT-safe (they are set-up and control-thread calls).

#include <cstdio>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::platform {

/// Starts the platform's real-time core for this process. Linux: there is none; returns success.
///
/// Xenomai 3 Cobalt: calls libcobalt's `xenomai_init()` once per process: it binds the process to
/// the Cobalt core, locks memory (mlockall) and makes the calling thread a Cobalt thread
/// (SCHED_OTHER, Cobalt's weak class). vigil's programs are linked without libcobalt's automatic
/// start-up (`xeno-config --no-auto-init`), which would read the command line before main() and
/// act on `--help`, `--version`, `--verbose`, ... itself: a program parses its own command line
/// first, then calls this (docs/guide/xenomai-cobalt.md). Xenomai's own options are not read:
/// libcobalt gets only the program name, so its defaults apply.
///
/// Without an explicit call, the first vigil call that needs Cobalt makes it:
/// `setup_realtime_process()`, `deploy::System::start()`, `Thread::spawn` of a SCHED_FIFO thread.
/// Until then `now_ns()` reads Linux's CLOCK_MONOTONIC (Cobalt's is the same clock on Dovetail
/// kernels; on I-pipe kernels, call this before taking timestamps).
///
/// Must run on the main thread (libcobalt's rule: the main thread becomes the core's first
/// thread); from another thread before Cobalt is initialised it returns an error (EPERM) naming
/// the rule. Thread-safe and idempotent: later calls return success at once. On a kernel without
/// the Cobalt core libcobalt prints `Cobalt core not enabled in kernel` and ends the process
/// (exit status 1): it does not return.
[[nodiscard]] expected<void, Error> initialize() noexcept;

/// The same, handing libcobalt `argc`/`argv` so that it reads and removes its own options
/// (`--cpu-affinity`, `--main-prio`, `--print-buffer-size`, ...; see Xenomai's documentation);
/// `argc` and `argv` then hold what is left. libcobalt also acts on `--help`, `--version` and
/// `--dump-config` (and on unambiguous prefixes of its long options, e.g. `--vers`) by printing
/// and ending the process: pass only the arguments meant for Xenomai. Error (EALREADY) when
/// Cobalt was already initialised: the options could not be applied, argv is left alone. Linux:
/// nothing is read, argv is left alone, success.
[[nodiscard]] expected<void, Error> initialize(int& argc, char**& argv) noexcept;

/// True once the real-time core is initialised (Linux: always).
[[nodiscard]] bool initialized() noexcept;

/// True when `stream` is a terminal (for colour and in-place redraw decisions).
[[nodiscard]] bool is_terminal(std::FILE* stream) noexcept;

/// Installs handlers so that SIGINT and SIGTERM set a flag instead of killing the process; read
/// it with stop_requested(). The handlers only store to an atomic (async-signal-safe).
void install_stop_signals() noexcept;

/// True once SIGINT or SIGTERM arrived after install_stop_signals().
[[nodiscard]] bool stop_requested() noexcept;

}  // namespace vigil::platform
