// must compile
// Twin of log_unsupported_argument: the container's size and first element are numbers.
#include <vector>

#include "vigil/log/log.hpp"
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() { VIGIL_LOG_INFO("{} setpoints, first {}", setpoints_.size(), setpoints_[0]); }

 private:
  std::vector<double> setpoints_ = {1.0};
};

void use() { Motor m; }
