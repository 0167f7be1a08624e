// must compile
// Twin of hide_configure_hook: the same member under another name.
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool configure_from(const std::string&) { return true; }
};

void use() { Motor m; }
