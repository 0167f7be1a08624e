// must compile
// Twin of hide_cycle_hook: the same member under another name.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void cycle_step(vigil::CycleContext&) {}
};

void use() { Motor m; }
