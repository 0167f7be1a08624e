// Fuzz target: a monitor thresholds file (vigil check-config, live reload of thresholds):
// YAML loading with vigil's limits, then the thresholds schema.
#include "fuzz_support.hpp"
#include "vigil/monitor/thresholds.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  vigil::fuzz::check_result(vigil::load_thresholds_string(text, "fuzz.yaml"), "fuzz.yaml");
  return 0;
}
