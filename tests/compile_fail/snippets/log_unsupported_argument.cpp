// expect: this argument type cannot be logged from the real-time path
// VIGIL_LOG_*: only numbers, bool, char, enums, pointers and strings are copied into a record;
// a container would need formatting (or allocation) on the RT thread.
#include <vector>

#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() { VIGIL_LOG_INFO("setpoints {}", setpoints_); }

 private:
  std::vector<double> setpoints_;
};

void use() { Motor m; }
