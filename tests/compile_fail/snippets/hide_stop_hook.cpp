// expect: your class declares `stop_hook`, a framework hook name
// expect: write `on_stop()` for stopping work
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void stop_hook(bool /*emergency*/) {}
};

void use() { Motor m; }
