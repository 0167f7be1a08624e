// must compile
// Twin of private_on_configure: with the friend declaration.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
  friend class vigil::Task<Motor>;

 public:
  Motor() : Task("motor") {}
  void on_update() {}

 private:
  bool on_configure() { return true; }
};

void use() { Motor m; }
