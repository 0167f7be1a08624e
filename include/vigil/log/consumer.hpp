#pragma once
/// @file
/// `RecordConsumer`: what the supervisor hands log records to. The component aggregator forwards
/// every `LogRecord` it drains to the consumer set with `set_log_consumer()` (the log module's
/// `LogService` is one); this interface is all the supervisor knows of the log module.

#include <cstdint>
#include <string_view>

#include "vigil/log/record.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::log {

/// Receives the log records drained from components' ports. Called on the supervisor thread
/// only, in each port's order. Not RT-safe (it formats and writes).
class RecordConsumer {
 public:
  virtual ~RecordConsumer() = default;
  /// One record of component `component` (registry id `id`).
  virtual void on_record(std::uint32_t id, std::string_view component, const LogRecord& record) = 0;
  /// After each supervisor cycle; `now` is the supervisor's clock.
  virtual void on_supervisor_cycle(Nanos /*now*/) {}
};

}  // namespace vigil::log
