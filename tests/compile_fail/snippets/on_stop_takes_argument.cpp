// expect: your class declares `on_stop` but Task cannot call it as `on_stop()`
// An on_stop that takes arguments would never be called: Task calls on_stop().
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool on_stop(int) { return true; }
};

void use() { Motor m; }
