// must compile
// Task<Derived, Traits>: private hooks need the friend declaration of that specialisation.
#include <cstddef>

#include "vigil/task/task.hpp"

struct SmallPort {
  static constexpr std::size_t port_capacity = 16;
};

class Motor : public vigil::Task<Motor, SmallPort> {
  friend class vigil::Task<Motor, SmallPort>;

 public:
  Motor() : Task("motor") {}

 private:
  void on_update() {}
  bool on_start() { return true; }
};

void use() { Motor m; }
