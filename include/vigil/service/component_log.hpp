#pragma once
/// @file
/// `ComponentLog`: the components' real-time log as a part of the pipeline. It is an output (at
/// start it becomes the aggregator's log consumer: the records the supervisor drains are
/// formatted off the real-time threads into its sinks; at stop it flushes and lets go) and a
/// contributor (each cycle's component reports get their log counts and last lines, which the
/// JSON, the detail view and `/api/v1/reports` show). `add_output()` registers it as both.
///
/// ```cpp
/// auto& log = service.add_output<vigil::service::ComponentLog>();
/// log.logs().add_sink(std::make_shared<vigil::log::StreamSink>(stderr));
/// ```
///
/// Threads as `Output` and `Contributor`; the sinks run on the supervisor's thread. Not RT-safe.

#include <cstddef>
#include <memory>
#include <string>

#include "vigil/export/output.hpp"
#include "vigil/export/outputs.hpp"
#include "vigil/log/service.hpp"
#include "vigil/log/sinks.hpp"
#include "vigil/service/contributor.hpp"

namespace vigil::service {

class ComponentLog final : public exporter::Output, public Contributor, public exporter::TextPanel {
 public:
  /// `recent_lines`: the last lines of each component added to its report.
  explicit ComponentLog(log::LogServiceOptions options = {}, std::size_t recent_lines = 5)
      : logs_(options), recent_lines_(recent_lines) {}
  /// Detaches from the aggregator if stop() was not called.
  ~ComponentLog() override;
  /// The log service: add sinks before the pipeline starts.
  [[nodiscard]] log::LogService& logs() noexcept { return logs_; }
  /// Keeps the last `lines` lines for a live view's panel (`append`).
  void show_tail(std::size_t lines);

  expected<void, Error> start(exporter::OutputContext& context) override;
  void stop(const exporter::Snapshot& final_snapshot) override;
  void contribute(exporter::Snapshot& snapshot) override;
  /// "log (N lines so far; the last 8 here):" and the lines, when a tail is shown.
  void append(std::string& out) const override;

 private:
  log::LogService logs_;
  std::size_t recent_lines_;
  std::shared_ptr<log::TailSink> tail_;
  std::size_t tail_lines_ = 0;
  supervisor::ComponentAggregator* aggregator_ = nullptr;
};

}  // namespace vigil::service
