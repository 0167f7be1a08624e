// expect: on_update() must return void
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  int on_update() { return 0; }
};

void use() { Motor m; }
