// must compile
// Twin of on_cleanup_returns_int: returns bool.
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool on_configure() { return true; }
  vigil::expected<void, std::string> on_start() { return {}; }
  bool on_stop() { return true; }
  bool on_cleanup() { return true; }
};

void use() { Motor m; }
