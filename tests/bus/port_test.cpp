#include "vigil/bus/port.hpp"

#include <atomic>
#include <catch2/catch.hpp>
#include <thread>
#include <variant>
#include <vector>

using vigil::Port;

namespace {
using Small = std::variant<int, double>;
// A message the size of a task message (the bus knows no message type of its own).
struct Wide {
  char bytes[120];
};
using Message = std::variant<Wide, int>;
}  // namespace

TEST_CASE("Port holds exactly its capacity", "[bus][port]") {
  Port<Small, 8> p;
  CHECK(p.capacity() == 8);
  for (int i = 0; i < 8; ++i) REQUIRE(p.try_push(Small{i}));
  CHECK(p.read_available() == 8);
  CHECK_FALSE(p.try_push(Small{99}));
  CHECK(p.dropped() == 1);
}

TEST_CASE("Port drops the newest message and counts it when full", "[bus][port]") {
  Port<Small, 4> p;
  for (int i = 0; i < 10; ++i) (void)p.try_push(Small{i});
  CHECK(p.dropped() == 6);
  Small out[8];
  const auto n = p.pop(out, 8);
  REQUIRE(n == 4);
  for (int i = 0; i < 4; ++i) CHECK(std::get<int>(out[i]) == i);  // the oldest survive
  CHECK(p.read_available() == 0);
  REQUIRE(p.try_push(Small{42}));
  CHECK(p.dropped() == 6);
}

TEST_CASE("Port pushes are noexcept and never allocate by construction", "[bus][port]") {
  Port<Message, 16> p;
  STATIC_REQUIRE(noexcept(p.try_push(std::declval<const Message&>())));
  STATIC_REQUIRE(noexcept(p.pop(nullptr, 0)));
  STATIC_REQUIRE(sizeof(Port<Message, 16>) >= 16 * sizeof(Message));  // storage is inline
}

TEST_CASE("Port delivers every message once, in order, across threads", "[bus][port]") {
  // Producer/consumer stress with a checksum (atomic_queue's test): run under TSan in CI.
  constexpr int kCount = 200000;
  Port<Small, 64> p;
  std::atomic<bool> go{false};
  long long produced_sum = 0;
  std::thread producer([&] {
    while (!go) std::this_thread::yield();
    for (int i = 0; i < kCount; ++i) {
      while (!p.try_push(Small{i})) std::this_thread::yield();
      produced_sum += i;
    }
  });
  long long consumed_sum = 0;
  int expected = 0;
  bool in_order = true;
  go = true;
  Small buf[32];
  while (expected < kCount) {
    const auto n = p.pop(buf, 32);
    for (std::size_t i = 0; i < n; ++i) {
      const int v = std::get<int>(buf[i]);
      in_order = in_order && v == expected;
      consumed_sum += v;
      ++expected;
    }
  }
  producer.join();
  CHECK(in_order);
  CHECK(consumed_sum == produced_sum);
}
