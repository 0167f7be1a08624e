// expect: on_cleanup() must return bool or vigil::expected<void, E>
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool on_configure() { return true; }
  vigil::expected<void, std::string> on_start() { return {}; }
  bool on_stop() { return true; }
  int on_cleanup() { return 0; }
};

void use() { Motor m; }
