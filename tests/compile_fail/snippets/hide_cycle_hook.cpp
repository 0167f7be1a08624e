// expect: your class declares `cycle_hook`, a framework hook name
// The hook an activity calls each cycle: another signature hides it.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void cycle_hook(vigil::CycleContext&) {}
};

void use() { Motor m; }
