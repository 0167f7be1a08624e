// minimal_component: the one-line instrumentation story.
//
// A component inherits vigil::Task<Motor> (the one line) and writes on_update(). Everything
// else here is the set-up a real program has anyway (a periodic activity) plus the supervision
// pipeline that reports on it: one vigil::SupervisionService.
#include <cmath>
#include <cstdio>
#include <thread>

#include "vigil/vigil.hpp"

class Motor : public vigil::Task<Motor> {  // <- the one line
 public:
  Motor() : Task("motor") {}
  void on_update() {
    // A PD law on a simulated motor, integrated in 1000 small steps (a few microseconds).
    const double target = std::sin(static_cast<double>(cycles()) * 1e-3);
    for (int i = 0; i < 1000; ++i) {
      velocity_ += (40.0 * (target - position_) - 2.0 * velocity_) * 1e-6;
      position_ += velocity_ * 1e-6;
    }
  }

 private:
  double position_ = 0;
  double velocity_ = 0;
};

int main() {
  vigil::platform::setup_realtime_process();

  // The supervision pipeline, once per process: a supervisor thread draining every component's
  // port, a monitor checking what it collected, the summary printed at stop.
  vigil::SupervisionService supervision({.details_at_stop = true});
  if (auto r = supervision.start(); !r) {
    std::fprintf(stderr, "cannot supervise: %s\n", r.error().message.c_str());
    return 1;
  }

  // The component, on a 1 kHz FIFO thread (SCHED_OTHER, reported, without the privilege).
  Motor motor;
  motor.configure();
  vigil::PeriodicActivity activity(motor, {.name = "control",
                                           .period_ns = vigil::kNanosPerMilli,
                                           .policy = vigil::SchedPolicy::Fifo,
                                           .priority = 80});
  if (auto r = activity.start(); !r) {
    std::fprintf(stderr, "cannot start: %s\n", r.error().message.c_str());
    return 1;
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));
  activity.stop();

  const vigil::ReportSet reports = supervision.stop();  // last drain, summary and details
  return reports.find("motor") != nullptr ? 0 : 1;
}
