// must compile
// Twin of on_update_returns_int: returns void.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
