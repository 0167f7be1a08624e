#pragma once
/// @file
/// `default_registry()`: the process's registry of component ports, for the one-line use case.
/// Task<Derived> and Instrumentation join it unless given another registry; the supervisor of
/// components drains it unless given another.

#include "vigil/bus/registry.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::task {

/// The registry of ports that carry component messages.
using ComponentRegistry = Registry<Message>;

/// The process's default registry of components. Components join it unless given another.
/// Thread-safe; created on first use (function-local static). Not RT-safe (its first call may
/// allocate): components call it from their constructors, never from a cycle.
ComponentRegistry& default_registry();

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::ComponentRegistry;
using task::default_registry;
}  // namespace vigil
