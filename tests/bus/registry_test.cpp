#include "vigil/bus/registry.hpp"

#include <algorithm>
#include <catch2/catch.hpp>
#include <string>
#include <variant>
#include <vector>

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

TEST_CASE("Members leave in any order: the rest are collected by id, each leaver once",
          "[bus][registry]") {
  Registry<V> reg;
  constexpr int kMembers = 200;
  std::vector<Membership<V, 2>> members;
  members.reserve(kMembers);
  for (int i = 0; i < kMembers; ++i) members.push_back(reg.join<2>("m" + std::to_string(i)));
  std::vector<std::shared_ptr<RegistryEntry<V>>> out;
  reg.collect(out);
  REQUIRE(out.size() == kMembers);

  // Leave in a scrambled order (a stride coprime with the count), collecting between leaves.
  std::vector<std::uint32_t> alive;
  for (const auto& m : members) alive.push_back(m.id());
  std::vector<std::uint32_t> seen_leaving;
  for (int k = 0; k < kMembers; ++k) {
    auto& m = members[static_cast<std::size_t>((k * 73) % kMembers)];
    const std::uint32_t id = m.id();
    m.leave();
    std::erase(alive, id);
    CHECK(reg.size() == alive.size());
    if (k % 7 == 0 || k == kMembers - 1) {
      reg.collect(out);
      std::vector<std::uint32_t> open;
      for (std::size_t i = 0; i < out.size(); ++i) {
        if (i > 0) CHECK(out[i - 1]->id < out[i]->id);  // ordered by id
        if (out[i]->closed.load()) {
          seen_leaving.push_back(out[i]->id);
        } else {
          open.push_back(out[i]->id);
        }
      }
      CHECK(open == alive);  // `alive` is in id order: erase keeps it so
    }
  }
  std::sort(seen_leaving.begin(), seen_leaving.end());
  CHECK(std::adjacent_find(seen_leaving.begin(), seen_leaving.end()) == seen_leaving.end());
  CHECK(seen_leaving.size() == kMembers);  // each leaver handed over exactly once
  CHECK(reg.size() == 0);
}
