// expect: your class declares `start_hook`, a framework hook name
// A private member hides the framework hook just the same.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}

 private:
  bool start_hook(int) { return true; }
};

void use() { Motor m; }
