// must compile
// Every optional hook, with both kinds of result.
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  vigil::expected<void, std::string> on_configure() { return {}; }
  bool on_start() { return true; }
  bool on_stop() { return true; }
  vigil::expected<void, int> on_cleanup() { return vigil::unexpected(3); }
};

void use() { Motor m; }
