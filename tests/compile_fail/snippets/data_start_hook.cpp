// expect: your class declares `start_hook`, a framework hook name
// A data member named like a framework hook hides it too.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  int start_hook = 0;
};

void use() { Motor m; }
