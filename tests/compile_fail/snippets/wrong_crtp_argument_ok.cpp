// must compile
// Twin of wrong_crtp_argument: Task<Motor>.
#include "vigil/task/task.hpp"

struct Pump {
  void on_update() {}
};

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
