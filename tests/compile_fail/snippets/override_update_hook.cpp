// expect-GNU: overriding final function
// expect-Clang: overrides a 'final' function
// expect: your class declares `update_hook`, a framework hook name
// Overriding a framework hook: `final` makes it an error, and check_author() adds the hint.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  void update_hook() noexcept override {}
};

void use() { Motor m; }
