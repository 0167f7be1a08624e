// The consumer package's program: one component of its own, stepped 100 times, supervised by
// vigil's pipeline found through find_package(vigil). Exits 0 when the report counts the cycles.
#include <cstdio>

#include "vigil/vigil.hpp"

namespace {

class Joint : public vigil::Task<Joint> {
 public:
  explicit Joint(vigil::ComponentRegistry& registry) : Task("joint", {}, registry) {}
  void on_update() { position_ += 0.001; }

 private:
  double position_ = 0;
};

}  // namespace

int main() {
  vigil::ComponentRegistry registry;
  vigil::SupervisionService supervision(
      {.registry = &registry, .monitor_thread = false, .summary_file = nullptr});
  Joint joint(registry);
  vigil::ManualActivity activity(joint, {.name = "manual"});
  if (!joint.configure() || !activity.start() || !supervision.start()) {
    std::fprintf(stderr, "vigil_colcon_consumer: cannot start\n");
    return 1;
  }
  for (int i = 0; i < 100; ++i) activity.step();
  activity.stop();
  const vigil::ReportSet reports = supervision.stop();  // last drain, last cycle
  const vigil::Report* r = reports.find("joint");
  if (r == nullptr || r->counters.cycles != 100) {
    std::fprintf(stderr, "vigil_colcon_consumer: expected 100 cycles of 'joint', got %llu\n",
                 r == nullptr ? 0ULL : static_cast<unsigned long long>(r->counters.cycles));
    return 1;
  }
  std::printf("vigil %s from the workspace: 'joint' ran %llu cycles, status %s\n", vigil::kVersion,
              static_cast<unsigned long long>(r->counters.cycles),
              vigil::to_string(r->status.level()));
  return 0;
}
