// expect: Derived must inherit vigil::Task<Derived> (CRTP)
// The CRTP argument must be the component itself.
#include "vigil/task/task.hpp"

struct Pump {
  void on_update() {}
};

class Motor : public vigil::Task<Pump> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
