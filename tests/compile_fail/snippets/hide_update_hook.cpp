// expect: your class declares `update_hook`, a framework hook name
// Another signature does not override: it hides the framework hook.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void update_hook(int) {}
};

void use() { Motor m; }
