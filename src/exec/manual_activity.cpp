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
  task_.attach(&info_);
}

ManualActivity::~ManualActivity() { task_.attach(nullptr); }

bool ManualActivity::start(Nanos first_release_ns) {
  schedule_.start(first_release_ns != 0 ? first_release_ns : config_.clock.now());
  missed_carry_ = 0;
  return task_.start();
}

bool ManualActivity::stop() { return task_.stop(); }

bool ManualActivity::step() noexcept {
  if (task_.state() != TaskState::Running) return false;
  CycleContext c;
  c.clock = &config_.clock;
  if (config_.period_ns > 0) {
    c.release_ns = schedule_.release();
    c.period_ns = config_.period_ns;
    c.missed_before = missed_carry_;
  }
  const bool ok = task_.update(c);
  if (config_.period_ns > 0) {
    const Nanos end = c.end_ns != 0 ? c.end_ns : config_.clock.now();
    const auto o = schedule_.advance(end);
    missed_carry_ = o.missed;
    if (o.limit_reached) {
      task_.raise_exception(Hook::Update, "vigil::OverrunLimit", "overrun limit reached");
    }
  }
  return ok;
}

}  // namespace vigil::exec
