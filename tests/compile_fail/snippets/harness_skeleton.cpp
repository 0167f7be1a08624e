// must compile
// The skeleton every snippet starts from: a minimal component, constructed in a function so that
// Task<Motor>'s virtual functions, and the checks they reach, are instantiated.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
