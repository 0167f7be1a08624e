// expect: on_configure() must return bool or vigil::expected<void, E>
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  int on_configure() { return 1; }
};

void use() { Motor m; }
