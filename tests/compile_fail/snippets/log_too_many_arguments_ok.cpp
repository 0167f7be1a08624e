// must compile
// Twin of log_too_many_arguments: eleven doubles fill the 88 bytes exactly.
#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {
    const double q = 1.0;
    VIGIL_LOG_INFO("{} {} {} {} {} {} {} {} {} {} {}", q, q, q, q, q, q, q, q, q, q, q);
  }
};

void use() { Motor m; }
