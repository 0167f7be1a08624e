// expect: on_start() must return bool or vigil::expected<void, E>
// vigil::expected<T, E> with a value type other than void is not a hook result.
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  vigil::expected<int, std::string> on_start() { return 1; }
};

void use() { Motor m; }
