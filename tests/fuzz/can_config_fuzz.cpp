// Fuzz target: a CAN configuration file (vigil can-stats -c, CAN supervision): YAML loading with
// vigil's limits, the schema, the filter compiled and run on a few frames, thresholds looked up.
#include "fuzz_support.hpp"
#include "vigil/can/can_config.hpp"
#include "vigil/can/filter.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace vigil::can;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto config = load_can_config_string(text, "fuzz.yaml");
  vigil::fuzz::check_result(config, "fuzz.yaml");
  if (!config) return 0;
  if (auto filter = Filter::compile(config->filter)) {
    const NodeMap map = NodeMap::of(config->node_map);
    for (std::uint32_t id : {0x000u, 0x181u, 0x60Bu, 0x7FFu, 0x18FEF121u}) {
      Frame f{};
      f.id = id;
      f.length = 8;
      (void)filter->matches(f, Direction::Rx, map);
    }
  }
  for (const NodeConfig& n : config->nodes) (void)config->thresholds_for(0, n.node);
  (void)config->group_specs();
  return 0;
}
