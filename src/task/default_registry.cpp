#include "vigil/task/default_registry.hpp"

#include "vigil/task/shm_messages.hpp"

namespace vigil::task {

ComponentRegistry& default_registry() {
  static ComponentRegistry registry;
  // VIGIL_SUPERVISOR=<name>: the ports of the components that join go to shared memory, where
  // `vigil supervise --name <name>` drains them (docs/guide/multi-process.md).
  static const bool placed =
      bus::place_from_environment(registry, kShmMessageSchema, kShmStickyMessages);
  (void)placed;
  return registry;
}

}  // namespace vigil::task
