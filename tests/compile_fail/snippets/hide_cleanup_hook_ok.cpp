// must compile
// Twin of hide_cleanup_hook: the same member template under another name.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  template <class T>
  void release(T) {}
};

void use() { Motor m; }
