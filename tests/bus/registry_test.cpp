#include "vigil/bus/registry.hpp"

#include <catch2/catch.hpp>
#include <variant>

using namespace vigil;
using namespace vigil::bus;

namespace {
using V = std::variant<int>;
}

TEST_CASE("Registry ids are unique and the generation changes on join and leave",
          "[bus][registry]") {
  Registry<V> reg;
  const auto g0 = reg.generation();
  auto a = reg.join<8>("a");
  const auto g1 = reg.generation();
  auto b = reg.join<8>("a");  // names need not be unique
  CHECK(g1 != g0);
  CHECK(a.id() != b.id());
  CHECK(reg.size() == 2);
  a.leave();
  CHECK(reg.size() == 1);
  CHECK(reg.generation() != g1);
  a.leave();  // idempotent
  CHECK(reg.size() == 1);
}

TEST_CASE("A member that joined and left between two collections is still handed over once",
          "[bus][registry]") {
  Registry<V> reg;
  std::vector<std::shared_ptr<RegistryEntry<V>>> out;
  reg.collect(out);
  CHECK(out.empty());
  {
    auto m = reg.join<4>("ephemeral");
    REQUIRE(m.port()->try_push(V{7}));
  }
  reg.collect(out);
  REQUIRE(out.size() == 1);
  CHECK(out[0]->closed.load());
  CHECK(out[0]->port->read_available() == 1);  // its message is still there to drain
  reg.collect(out);
  CHECK(out.empty());
}

TEST_CASE("Membership moves keep the port", "[bus][registry]") {
  Registry<V> reg;
  auto a = reg.join<4>("a");
  auto* port = a.port();
  Membership<V, 4> b = std::move(a);
  CHECK(b.port() == port);
  CHECK_FALSE(a.joined());  // NOLINT(bugprone-use-after-move): moved-from is empty by contract
  CHECK(reg.size() == 1);
}
