// expect: vigil-harness-sanity
// The skeleton plus an error: proves that the harness sees a failure and reads its text.
#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
};

static_assert(false, "vigil-harness-sanity");

void use() { Motor m; }
