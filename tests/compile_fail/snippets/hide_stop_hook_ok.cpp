// must compile
// Twin of hide_stop_hook: the same member under another name.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void stop_now(bool /*emergency*/) {}
};

void use() { Motor m; }
