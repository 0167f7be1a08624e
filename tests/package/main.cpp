// Built against the installed package in CI: proves find_package(vigil) + vigil::vigil work.
#include <cstdio>

#include "vigil/vigil.hpp"

int main() {
  const vigil::Nanos t = vigil::platform::now_ns();
  std::printf("vigil %s found; clock reads %lld ns\n", vigil::kVersion, static_cast<long long>(t));
  return t > 0 ? 0 : 1;
}
