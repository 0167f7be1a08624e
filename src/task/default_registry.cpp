#include "vigil/task/default_registry.hpp"

namespace vigil {

ComponentRegistry& default_registry() {
  static ComponentRegistry registry;
  return registry;
}

}  // namespace vigil
