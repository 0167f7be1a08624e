// must compile
// Twin of private_hide_start_hook: the same private member under another name.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}

 private:
  bool start_step(int) { return true; }
};

void use() { Motor m; }
