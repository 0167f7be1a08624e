// expect: define `void on_update()` in your component
// expect: private with `friend class vigil::Task<Derived>;`
// A private on_update() is out of Task's reach without the friend declaration.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}

 private:
  void on_update() {}
};

void use() { Motor m; }
