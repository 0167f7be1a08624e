#pragma once
/// @file
/// The stack an activity's thread gets unless its configuration says otherwise.

#include <cstddef>

namespace vigil::exec {

/// Stack of an activity's thread (PeriodicConfig::stack_bytes, TriggeredConfig::stack_bytes)
/// unless its configuration says otherwise: 512 KiB. The thread runs the components' code, whose
/// needs vigil cannot know: this leaves room for components with large local arrays (vigil's own
/// part of a cycle uses a few KiB). Under mlockall the whole stack is resident and locked, so
/// this is what an activity's thread costs in RAM (docs/design/memory.md). Set it per activity
/// in the deployment (`stack: 1MiB`) or in the configuration.
inline constexpr std::size_t kDefaultActivityStackBytes = std::size_t{512} * 1024;

}  // namespace vigil::exec

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using exec::kDefaultActivityStackBytes;
}  // namespace vigil
