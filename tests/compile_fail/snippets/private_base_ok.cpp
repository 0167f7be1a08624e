// must compile
// Twin of private_base: public inheritance.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

void use() { Motor m; }
