#pragma once
/// @file
/// `Source`: what a supervision pipeline drains into its aggregator. Two exist: the components
/// of this process (`RegistrySource`, the in-process ports of a registry) and the shared-memory
/// segments of other processes (`SegmentSource`, vigil/service/segment_source.hpp, what `vigil
/// supervise` drains). Both feed the same aggregator protocol (join, batches of messages, drain,
/// leave, cycle), so everything after the aggregator (monitor, contributors, outputs) is the same
/// pipeline. `SupervisionService` builds the source its options ask for. Not RT-safe.

#include <cstddef>
#include <memory>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/default_registry.hpp"

namespace vigil::service {

class Source {
 public:
  virtual ~Source() = default;
  /// Starts the source's drain thread. Fails when the thread (or what it needs) cannot start.
  virtual expected<void, Error> start() = 0;
  /// Stops and joins the thread after a last full drain. Idempotent.
  virtual void stop() = 0;
  /// One drain in the calling thread (when the thread does not run); returns the messages.
  virtual std::size_t step() = 0;
  [[nodiscard]] virtual bool running() const = 0;
};

/// The components of this process: a `ComponentDrainLoop` draining every port of a registry.
class RegistrySource final : public Source {
 public:
  RegistrySource(ComponentRegistry& registry, supervisor::ComponentAggregator& aggregator,
                 supervisor::DrainOptions options)
      : supervisor_(registry, aggregator, std::move(options)) {}
  expected<void, Error> start() override { return supervisor_.start(); }
  void stop() override { supervisor_.stop(); }
  std::size_t step() override { return supervisor_.step(); }
  [[nodiscard]] bool running() const override { return supervisor_.running(); }
  [[nodiscard]] supervisor::ComponentDrainLoop& supervisor() noexcept { return supervisor_; }

 private:
  supervisor::ComponentDrainLoop supervisor_;
};

}  // namespace vigil::service
