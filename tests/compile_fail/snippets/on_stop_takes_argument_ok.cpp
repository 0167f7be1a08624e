// must compile
// Twin of on_stop_takes_argument: no argument.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool on_stop() { return true; }
};

void use() { Motor m; }
