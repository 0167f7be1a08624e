#pragma once
/// @file
/// The binding of vigil's component messages (`vigil::Message`) to shared-memory ports: their
/// schema, which of them are "sticky" (mirrored so a daemon that attaches late still gets them),
/// the daemon-side check of a decoded message, and the one call that sends this process's
/// components to a `vigil supervise` daemon.
///
/// Selecting shared memory never changes a component's class: a component joins the registry it
/// was given (by default `default_registry()`), and that registry places the port in shared
/// memory when (1) the environment variable VIGIL_SUPERVISOR=<name> is set when the default
/// registry is first used, (2) a deployment file says `supervision: {shared_memory: <name>}`, or
/// (3) the program calls `supervise_in_shared_memory("<name>")` before its components are made.

#include <cstdint>
#include <string>

#include "vigil/bus/registry.hpp"
#include "vigil/bus/shm_layout.hpp"
#include "vigil/bus/shm_session.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::task {

/// The schema of `Message` in a segment. Increment the version when a message type changes
/// without changing size (sizes are part of the id already).
inline constexpr bus::ShmSchema kShmMessageSchema =
    bus::make_shm_schema<Message>("vigil.Message", 1);

/// Messages mirrored in their mailbox on every push: rare ones a late daemon needs (identity,
/// the latest state change and exception). Samples are mirrored only when dropped.
inline constexpr std::uint32_t kShmStickyMessages =
    bus::shm_type_mask<Message, TaskInfo, StateChange, ExceptionReport>();

/// Checks a message decoded from a segment before anyone reads it: every bool is 0 or 1, every
/// enum within its values, every string terminated, times within [0, 2^62) and a cycle's end not
/// before its start; strings are force-terminated. Returns false with the reason otherwise.
/// Daemon side, not RT-safe.
[[nodiscard]] bool check_shm_message(Message& m, std::string& why);

/// Places the ports of the components that join `registry` from now on in shared memory under
/// supervisor `name` (options: group). Fails for an invalid name or group. Not RT-safe.
expected<void, Error> place_in_shared_memory(Registry<Message>& registry, bus::ShmOptions options);

/// The one call: components created after it, in the default registry, are supervised by
/// `vigil supervise --name <name>` instead of in this process. Not RT-safe.
expected<void, Error> supervise_in_shared_memory(const std::string& name);

}  // namespace vigil::task

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using task::place_in_shared_memory;
using task::supervise_in_shared_memory;
}  // namespace vigil
