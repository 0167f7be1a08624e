// expect: define `void on_update()` in your component
// on_update() takes no arguments: an on_update(int) is not the cycle's work.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update(int) {}
};

void use() { Motor m; }
