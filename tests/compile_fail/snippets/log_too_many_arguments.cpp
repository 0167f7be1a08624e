// expect: too many arguments for one record
// VIGIL_LOG_*: a record has 88 bytes of arguments; twelve doubles need 96.
#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {
    const double q = 1.0;
    VIGIL_LOG_INFO("{} {} {} {} {} {} {} {} {} {} {} {}", q, q, q, q, q, q, q, q, q, q, q, q);
  }
};

void use() { Motor m; }
