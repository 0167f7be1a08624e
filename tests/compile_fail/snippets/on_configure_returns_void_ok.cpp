// must compile
// Twin of on_configure_returns_void: returns bool.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool on_configure() { return true; }
};

void use() { Motor m; }
