// A controller process of examples/multi_process: a few joint controllers at 1 kHz.
//
// Nothing here mentions shared memory or the daemon: the components are ordinary Task<Joint>s in
// the process's default registry. Started with VIGIL_SUPERVISOR=robot in its environment, the
// process sends their ports to `vigil supervise --name robot` instead of supervising them itself.
//
//   controller NAME [JOINTS] [--fault segv|abort|exit3 --after SECONDS]
//
// --fault makes the process end badly after SECONDS, to see what the daemon reports.
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "vigil/vigil.hpp"

namespace {

class Joint : public vigil::Task<Joint> {
 public:
  explicit Joint(std::string name) : Task(std::move(name)) {}
  void on_update() {
    // A PD law on a simulated joint, a few microseconds of work.
    const double target = std::sin(static_cast<double>(cycles()) * 1e-3);
    for (int i = 0; i < 300; ++i) {
      velocity_ += (40.0 * (target - position_) - 2.0 * velocity_) * 1e-6;
      position_ += velocity_ * 1e-6;
    }
  }

 private:
  double position_ = 0;
  double velocity_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s NAME [JOINTS] [--fault segv|abort|exit3 --after SECONDS]\n",
                 argv[0]);
    return 2;
  }
  const std::string name = argv[1];
  int joints = 3;
  std::string fault;
  double after = 3;
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--fault") == 0 && i + 1 < argc) {
      fault = argv[++i];
    } else if (std::strcmp(argv[i], "--after") == 0 && i + 1 < argc) {
      after = std::atof(argv[++i]);
    } else {
      joints = std::atoi(argv[i]);
    }
  }
  vigil::platform::install_stop_signals();  // Ctrl-C / SIGTERM: stop cleanly (components leave)
  vigil::platform::setup_realtime_process({.request_zero_cpu_latency = false});
  if (std::getenv("VIGIL_SUPERVISOR") == nullptr) {
    std::fprintf(stderr,
                 "%s: VIGIL_SUPERVISOR is not set: nobody will supervise these "
                 "components (see README.md)\n",
                 name.c_str());
  }

  std::vector<std::unique_ptr<Joint>> tasks;
  std::vector<std::unique_ptr<vigil::PeriodicActivity>> activities;
  for (int j = 0; j < joints; ++j) {
    tasks.push_back(std::make_unique<Joint>(name + ".joint" + std::to_string(j)));
    tasks.back()->configure();
    activities.push_back(std::make_unique<vigil::PeriodicActivity>(
        *tasks.back(), vigil::PeriodicConfig{.name = name,
                                             .period_ns = vigil::kNanosPerMilli,
                                             .policy = vigil::SchedPolicy::Fifo,
                                             .priority = 80}));
    if (auto r = activities.back()->start(); !r) {
      std::fprintf(stderr, "%s: cannot start: %s\n", name.c_str(), r.error().message.c_str());
      return 1;
    }
  }
  std::printf("%s: pid %d, %d joints at 1 kHz\n", name.c_str(),
              static_cast<int>(vigil::platform::self_identity().pid), joints);
  std::fflush(stdout);

  const auto start = std::chrono::steady_clock::now();
  while (!vigil::platform::stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!fault.empty() && elapsed >= after) {
      std::printf("%s: %s now\n", name.c_str(), fault.c_str());
      std::fflush(stdout);
      if (fault == "segv") std::raise(SIGSEGV);
      if (fault == "abort") std::abort();
      if (fault == "exit3") std::exit(3);  // components still running: they vanish with it
    }
  }
  for (auto& a : activities) a->stop();
  std::printf("%s: stopped\n", name.c_str());
  return 0;
}
