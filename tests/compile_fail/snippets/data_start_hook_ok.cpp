// must compile
// Twin of data_start_hook: the same data member under another name.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  int start_count = 0;
};

void use() { Motor m; }
