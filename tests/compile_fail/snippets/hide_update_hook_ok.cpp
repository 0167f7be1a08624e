// must compile
// Twin of hide_update_hook: the same member under another name.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void update_step(int) {}
};

void use() { Motor m; }
