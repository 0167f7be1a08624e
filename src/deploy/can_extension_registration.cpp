// Linked into every program that links vigil::deploy_can (an object file, not an archive member,
// so the linker always keeps it): registers the `can:` section before main() runs. Only
// internal-linkage symbols here, so the file may safely appear twice on a link line.
#include "vigil/deploy/can_extension.hpp"

namespace {
[[maybe_unused]] const bool kRegistered = (vigil::deploy::register_can_extension(), true);
}  // namespace
