// must compile
// Twin of missing_on_update: with on_update().
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  bool on_configure() { return true; }
  void on_update() {}
};

void use() { Motor m; }
