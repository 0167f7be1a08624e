// must compile
// Twin of on_update_takes_argument: no argument.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
