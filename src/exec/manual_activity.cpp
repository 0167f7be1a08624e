#include "vigil/exec/manual_activity.hpp"

namespace vigil::exec {

ManualActivity::ManualActivity(TaskCore& task, ManualConfig config)
    : task_(task),
      config_(std::move(config)),
      schedule_(config_.period_ns, config_.overrun_policy, config_.overrun_limit) {
  info_.name = config_.name;
  info_.period_ns = config_.period_ns;
  info_.overrun_policy = config_.overrun_policy;
  info_.threaded = false;
  context_.clock = &config_.clock;
  context_.period_ns = config_.period_ns > 0 ? config_.period_ns : 0;
  task_.attach(&info_);
}

ManualActivity::~ManualActivity() { task_.attach(nullptr); }

bool ManualActivity::start(Nanos first_release_ns) {
  schedule_.start(first_release_ns != 0 ? first_release_ns : config_.clock.now());
  missed_carry_ = 0;
  return task_.start();
}

bool ManualActivity::stop() { return task_.stop(); }

void ManualActivity::late(Nanos end) noexcept {
  const auto o = schedule_.advance(end);
  missed_carry_ = o.missed;
  if (o.limit_reached) {
    task_.raise_exception(Hook::Update, "vigil::OverrunLimit", "overrun limit reached");
  }
}

}  // namespace vigil::exec
