// expect: your class declares `on_configure` but Task cannot call it as `on_configure()`
// expect: public or private with `friend class vigil::Task<Derived>;`
// A private optional hook without the friend declaration would be silently skipped.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}

 private:
  bool on_configure() { return true; }
};

void use() { Motor m; }
