// expect: invalid type specifier
// VIGIL_LOG_*: a format spec that does not fit the argument's type is a compile error ({:d}
// on a string), as with fmt::format.
#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() { VIGIL_LOG_INFO("mode {:d}", "torque"); }
};

void use() { Motor m; }
