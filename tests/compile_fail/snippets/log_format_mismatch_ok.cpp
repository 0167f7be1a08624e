// must compile
// Twin of log_format_mismatch: as many arguments as replacement fields.
#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() { VIGIL_LOG_WARN("joint {} limit reached: {:.2f} rad", 3, 2.41); }
};

void use() { Motor m; }
