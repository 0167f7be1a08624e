// must compile
// Twin of log_format_bad_spec: {:>8} fits a string.
#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() { VIGIL_LOG_INFO("mode {:>8}", "torque"); }
};

void use() { Motor m; }
