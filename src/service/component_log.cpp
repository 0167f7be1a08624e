#include "vigil/service/component_log.hpp"

#include <fmt/format.h>

#include "vigil/export/log_report.hpp"

namespace vigil::service {

ComponentLog::~ComponentLog() {
  if (aggregator_ != nullptr) aggregator_->set_log_consumer(nullptr);
}

void ComponentLog::show_tail(std::size_t lines) {
  tail_ = std::make_shared<log::TailSink>(lines);
  tail_lines_ = lines;
  logs_.add_sink(tail_);
}

expected<void, Error> ComponentLog::start(exporter::OutputContext& context) {
  aggregator_ = &context.aggregator;
  aggregator_->set_log_consumer(&logs_);
  return {};
}

void ComponentLog::stop(const exporter::Snapshot& /*final_snapshot*/) {
  logs_.flush();  // after the last drain: the suppressed counts still pending
  if (aggregator_ != nullptr) aggregator_->set_log_consumer(nullptr);
  aggregator_ = nullptr;
}

void ComponentLog::contribute(exporter::Snapshot& snapshot) {
  exporter::add_log_lines(logs_, snapshot.reports, recent_lines_);
}

void ComponentLog::append(std::string& out) const {
  if (!tail_ || tail_->total() == 0) return;
  const auto lines = tail_->lines();
  out += fmt::format("\nlog ({} line{} so far; the last {} here):\n", tail_->total(),
                     tail_->total() == 1 ? "" : "s", tail_lines_);
  for (const auto& l : lines) out += "  " + l + '\n';
}

}  // namespace vigil::service
