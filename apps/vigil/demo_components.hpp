#pragma once
// The simulated robot of `vigil demo`: components registered in the factory under "demo.*".
#include "vigil/deploy/factory.hpp"
#include "vigil/task/task.hpp"

namespace vigil::demo {

/// Busy-waits `ns` nanoseconds (simulated computation).
void burn(Nanos ns) noexcept;

/// Registers the demo's component types (idempotent).
void register_components();

/// The built-in deployment of `vigil demo` (YAML).
extern const char* const kDemoDeployment;

}  // namespace vigil::demo
