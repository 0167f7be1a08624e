// expect: your class declares `configure_hook`, a framework hook name
// expect: write `on_configure()` for configuration work
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool configure_hook(const std::string&) { return true; }
};

void use() { Motor m; }
