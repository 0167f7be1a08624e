// expect: your class declares `cleanup_hook`, a framework hook name
// expect: write `on_cleanup()` for clean-up work
// A member template hides the framework hook too.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  template <class T>
  void cleanup_hook(T) {}
};

void use() { Motor m; }
