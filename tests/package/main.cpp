// Built against the installed package in CI (.ci/run): proves that find_package(vigil) and
// vigil::vigil work, and that a program of its own gets CAN supervision from a deployment's
// `can:` section just by linking the package (the section's extension registers itself), and
// that the HTTP server's module is found in the installation, not in the build tree.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <thread>

#include "vigil/build_config.hpp"
#include "vigil/can/sniffer.hpp"
#include "vigil/deploy/can_extension.hpp"
#include "vigil/deploy/deployment.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/export/http_server.hpp"
#include "vigil/vigil.hpp"

// The generated build flags are installed as vigil/build_config.hpp (was vigil/config.hpp).
static_assert(VIGIL_PLATFORM_LINUX + VIGIL_PLATFORM_COBALT == 1, "one platform");

namespace {

// A CAN I/O component of the user's: reads TPDO1 of two drives each cycle; drive 2 goes quiet.
class CanIo : public vigil::Task<CanIo> {
 public:
  explicit CanIo(const vigil::deploy::ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()) {
    auto* can = c.system->extension<vigil::deploy::CanExtension>();
    if (can == nullptr) throw std::runtime_error("no CAN extension: the can: section was ignored");
    sniffer_ = std::make_unique<vigil::can::Sniffer<64>>(
        can->registry(), c.name,
        vigil::can::SnifferOptions{.node_map = vigil::can::NodeMap::canopen()});
  }
  void on_update() {
    ++cycle_;
    for (std::uint32_t node = 1; node <= 2; ++node) {
      if (node == 2 && cycle_ > 10) continue;
      const vigil::Nanos t = vigil::platform::now_ns();
      auto f = vigil::can::Frame::classic(0x180 + node, {0x27});
      f.timestamp = t;
      sniffer_->on_read(f, t, t);
    }
  }

 private:
  std::uint64_t cycle_ = 0;
  std::unique_ptr<vigil::can::Sniffer<64>> sniffer_;
};
VIGIL_REGISTER_COMPONENT(CanIo, "user.can_io");

constexpr const char* kDeployment = R"(
name: package-consumer
activities: [{name: io, period: 5ms}]
components: [{name: can_io, type: user.can_io, activity: io}]
supervision: {lock_memory: false, monitor_period: 50ms}
can:
  node_map: canopen
  defaults: {not_responding: {after: 100ms}}
  nodes: {drive_1: {node: 1, bus: 0}, drive_2: {node: 2, bus: 0}}
)";

}  // namespace

int main() {
  std::printf("vigil %s found\n", vigil::kVersion);
  const auto module = vigil::exporter::http_module();
  if (!module) {
    std::fprintf(stderr, "%s\n", module.error().message.c_str());
    return 1;
  }
  const auto dir = std::filesystem::canonical(*module).parent_path();
  if (dir != std::filesystem::canonical(VIGIL_PACKAGE_MODULE_DIR)) {
    std::fprintf(stderr, "HTTP module %s is not the installation's (%s)\n", module->c_str(),
                 VIGIL_PACKAGE_MODULE_DIR);
    return 1;
  }
  std::printf("HTTP module: %s\n", module->c_str());
  auto spec = vigil::deploy::load_deployment_string(kDeployment, "<consumer>");
  if (!spec) {
    std::fprintf(stderr, "%s\n", vigil::config::to_string(spec.error()).c_str());
    return 1;
  }
  auto sys = vigil::deploy::System::create(std::move(*spec));
  if (!sys) {
    std::fprintf(stderr, "%s\n", vigil::config::to_string(sys.error()).c_str());
    return 1;
  }
  if (auto r = (*sys)->start(); !r) {
    std::fprintf(stderr, "cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  (*sys)->stop();
  const vigil::ReportSet reports = (*sys)->step_monitor();
  const vigil::Report* one = reports.find("can0/drive_1");
  const vigil::Report* two = reports.find("can0/drive_2");
  if (one == nullptr || two == nullptr) {
    std::fprintf(stderr, "no CAN node reports\n");
    return 1;
  }
  std::printf("can0/drive_1: %s, can0/drive_2: %s (%s)\n",
              std::string(vigil::to_string(one->status.level())).c_str(),
              std::string(vigil::to_string(two->status.level())).c_str(),
              two->status.summary().c_str());
  const bool ok = one->status.ok() && two->status.level() == vigil::StatusLevel::Error;
  return ok ? 0 : 1;
}
