// Built against the installed package in CI (and against a Cobalt install, see
// docs/design/platform.md): proves find_package(vigil) + vigil::vigil work. It spawns a thread so
// that the platform layer's thread code, Linux's or Cobalt's, is linked in too.
#include <atomic>
#include <cstdio>

#include "vigil/vigil.hpp"

int main() {
  const vigil::Nanos t = vigil::platform::now_ns();
  std::atomic<int> tid{0};
  auto thread = vigil::platform::Thread::spawn({.name = "consumer"},
                                               [&] { tid = vigil::platform::current_tid(); });
  if (!thread) {
    std::fprintf(stderr, "%s\n", thread.error().message.c_str());
    return 1;
  }
  thread->join();
  std::printf("vigil %s found; clock reads %lld ns; thread %d ran\n", vigil::kVersion,
              static_cast<long long>(t), tid.load());
  return t > 0 && tid.load() > 0 ? 0 : 1;
}
