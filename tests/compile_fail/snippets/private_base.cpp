// expect: inherit vigil::Task<Derived> publicly
// A class's bases are private by default.
#include "vigil/task/task.hpp"

class Motor : vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
