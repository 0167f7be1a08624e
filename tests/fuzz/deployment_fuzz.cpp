// Fuzz target: a deployment file (vigil demo --config, vigil check-config): YAML loading with
// vigil's limits, then the deployment schema, with two component types registered so that
// component entries get past the type check.
#include "fuzz_support.hpp"
#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/factory.hpp"

namespace {
const vigil::deploy::ComponentFactory& factory() {
  static vigil::deploy::ComponentFactory* const f = [] {
    auto* made = new vigil::deploy::ComponentFactory();
    const auto none = [](const vigil::deploy::ComponentContext&) {
      return std::unique_ptr<vigil::TaskCore>();
    };
    made->add("fuzz.a", none, "fuzz type a");
    made->add("demo.motor", none, "as in the demo");
    return made;
  }();
  return *f;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  vigil::fuzz::check_result(vigil::deploy::load_deployment_string(text, "fuzz.yaml", factory()),
                            "fuzz.yaml");
  return 0;
}
