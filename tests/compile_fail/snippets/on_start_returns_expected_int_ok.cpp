// must compile
// Twin of on_start_returns_expected_int: vigil::expected<void, std::string>, whose error
// refuses the transition and becomes its reason.
#include <string>

#include "vigil/task/task.hpp"

class Motor : public vigil::Task<Motor> {
 public:
  Motor() : Task("motor") {}
  void on_update() {}
  vigil::expected<void, std::string> on_start() { return {}; }
};

void use() { Motor m; }
