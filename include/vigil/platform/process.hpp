#pragma once
/// @file
/// Small process-level services for programs built on vigil: a terminal test and a clean stop on
/// Ctrl-C / SIGTERM. None of these is RT-safe (they are set-up and control-thread calls).

#include <cstdio>

namespace vigil::platform {

/// True when `stream` is a terminal (for colour and in-place redraw decisions).
[[nodiscard]] bool is_terminal(std::FILE* stream) noexcept;

/// Installs handlers so that SIGINT and SIGTERM set a flag instead of killing the process; read
/// it with stop_requested(). The handlers only store to an atomic (async-signal-safe).
void install_stop_signals() noexcept;

/// True once SIGINT or SIGTERM arrived after install_stop_signals().
[[nodiscard]] bool stop_requested() noexcept;

}  // namespace vigil::platform
