// expect: on_configure() must return bool or vigil::expected<void, E>
// A void hook could not refuse its transition: say true or false.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void on_configure() {}
};

void use() { Motor m; }
