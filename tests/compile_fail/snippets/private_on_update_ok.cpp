// must compile
// Twin of private_on_update: the hooks may be private with the friend declaration.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
  friend class vigil::Task<Motor>;

 public:
  Motor() : Task("motor") {}

 private:
  void on_update() {}
};

void use() { Motor m; }
