// expect: argument not found
// VIGIL_LOG_*: the format string is checked against the arguments at compile time (two
// replacement fields, one argument).
#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() { VIGIL_LOG_WARN("joint {} limit reached: {:.2f} rad", 3); }
};

void use() { Motor m; }
