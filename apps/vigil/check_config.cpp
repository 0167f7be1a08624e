// `vigil check-config FILE...`: validates deployment and thresholds files.
#include <cstdio>

#include "commands.hpp"
#include "demo_components.hpp"
#include "vigil/config/load.hpp"
#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/monitor/thresholds.hpp"

namespace vigil::app {

namespace {
bool looks_like_deployment(const config::Node& root) {
  return root.is_mapping() && (root.has("activities") || root.has("supervision") ||
                               root.has("outputs") || root["components"].is_sequence());
}
}  // namespace

int run_check_config(const CheckConfigOptions& o) {
  demo::register_components();
  int failures = 0;
  for (const auto& file : o.files) {
    auto root = config::load_file(file);
    if (!root) {
      std::fprintf(stderr, "%s\n", config::to_string(root.error()).c_str());
      ++failures;
      continue;
    }
    const bool deployment =
        o.kind == "deployment" || (o.kind == "auto" && looks_like_deployment(*root));
    if (deployment) {
      auto d = deploy::parse_deployment(*root);
      if (!d) {
        std::fprintf(stderr, "%s\n", config::to_string(d.error()).c_str());
        ++failures;
        continue;
      }
      const std::string name = d->name;
      const std::size_t activities = d->activities.size();
      const std::size_t components = d->components.size();
      // Build the system without starting it: components validate their parameters.
      if (auto sys = deploy::System::create(std::move(*d)); !sys) {
        std::fprintf(stderr, "%s\n", config::to_string(sys.error()).c_str());
        ++failures;
        continue;
      }
      std::printf("%s: OK (deployment '%s': %zu activities, %zu components)\n", file.c_str(),
                  name.c_str(), activities, components);
    } else {
      auto t = load_thresholds(*root);
      if (!t) {
        std::fprintf(stderr, "%s\n", config::to_string(t.error()).c_str());
        ++failures;
        continue;
      }
      std::printf("%s: OK (thresholds: defaults and %zu component overrides)\n", file.c_str(),
                  t->components.size());
    }
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace vigil::app
