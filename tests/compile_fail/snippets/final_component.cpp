// must compile
// A final component (the scan for misspelt optional hooks skips final classes).
#include "vigil/task/task.hpp"

class Motor final : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  bool on_configure() { return true; }
};

void use() { Motor m; }
