#pragma once
// Private to src/platform/cobalt/: whether libcobalt is initialised (core.cpp, initialize()).
// vigil's programs are linked with `xeno-config --no-auto-init`, so libcobalt starts only when
// vigil::platform::initialize() runs; until then no Cobalt service may be used. libcobalt's
// clock_gettime in particular must not be called before: its vDSO hook is not set up yet, and its
// fallback calls clock_gettime again (lib/cobalt/ticks.c, v3.2.7), without end.
//
// Includes no Xenomai header.

#include <atomic>

namespace vigil::platform::detail {

/// Set (release) once xenomai_init() has returned; never cleared.
extern std::atomic<bool> g_cobalt_ready;

/// True once libcobalt is initialised. RT-safe: one acquire load (a plain load on x86-64).
[[nodiscard]] inline bool cobalt_ready() noexcept {
  return g_cobalt_ready.load(std::memory_order_acquire);
}

}  // namespace vigil::platform::detail
