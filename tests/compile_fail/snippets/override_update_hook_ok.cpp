// must compile
// Twin of override_update_hook: the cycle's work goes in on_update().
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void step() noexcept {}
};

void use() { Motor m; }
