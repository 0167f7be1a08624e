// expect: define `void on_update()` in your component
// on_update() is required: it is the cycle's work.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  bool on_configure() { return true; }
};

void use() { Motor m; }
