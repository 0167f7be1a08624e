#pragma once
// The `can:` section of a deployment: a CAN registry for the sniffers of CAN I/O components, a
// CAN supervisor thread and a CAN monitor whose verdicts join the system's reports (one report
// per node and per group).
#include <memory>

#include "vigil/can/can_config.hpp"
#include "vigil/can/can_monitor.hpp"
#include "vigil/can/can_statistics.hpp"
#include "vigil/can/sniffer.hpp"
#include "vigil/deploy/system.hpp"

namespace vigil::app {

class CanExtension : public deploy::Extension {
 public:
  explicit CanExtension(can::CanConfig config);
  expected<void, Error> start() override;
  void stopping() override;
  void stop() override;
  void contribute(ReportSet& reports) override;

  [[nodiscard]] can::CanRegistry& registry() noexcept { return registry_; }
  [[nodiscard]] const can::CanConfig& config() const noexcept { return config_; }

 private:
  can::CanConfig config_;
  can::CanRegistry registry_;
  std::unique_ptr<can::CanAggregator> statistics_;
  std::unique_ptr<can::CanSupervisor> supervisor_;
  std::unique_ptr<can::CanMonitor> monitor_;
  Nanos stopped_at_ = 0;  // once stopping: the time liveness is judged at
};

/// Registers the extension for the `can:` section (idempotent).
void register_can_extension();

}  // namespace vigil::app
