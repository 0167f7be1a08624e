// Explicit thread stacks and malloc's arena bound: what a locked process costs in RAM.
#include <catch2/catch.hpp>
#include <string>

#include "support/stack.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/platform/thread.hpp"

using namespace vigil::platform;

namespace {
std::size_t stack_of(const ThreadConfig& config) {
  std::size_t bytes = 0;
  auto t = Thread::spawn(config, [&] { bytes = vigil::test::current_stack_bytes(); });
  REQUIRE(t.has_value());
  t->join();
  return bytes;
}
}  // namespace

TEST_CASE("A thread gets kDefaultStackBytes unless it asks for another stack",
          "[platform][thread][memory]") {
  using vigil::test::stack_serves;
  STATIC_REQUIRE(kDefaultStackBytes == 256 * 1024);
  // The system's default (glibc: ulimit -s, 8 MiB here) is more than 4 x vigil's default, so a
  // thread that got it would fail stack_serves.
  const std::size_t system = vigil::test::system_default_stack_bytes();
  REQUIRE(system > 4 * kDefaultStackBytes);
  CHECK(stack_serves(stack_of({.name = "default"}), kDefaultStackBytes));
  CHECK(stack_serves(stack_of({.name = "one_mib", .stack_bytes = 1024 * 1024}), 1024 * 1024));
  // 0 keeps the system's default.
  CHECK(stack_of({.name = "system", .stack_bytes = 0}) >= system);
}

TEST_CASE("A small explicit stack is raised to the minimum and not overrun by the prefault",
          "[platform][thread][memory]") {
  // 64 KiB of prefault in a 32 KiB stack would run into the guard page: at most half is touched.
  const std::size_t got =
      stack_of({.name = "small", .stack_bytes = 32 * 1024, .prefault_stack_bytes = 64 * 1024});
  CHECK(vigil::test::stack_serves(got, 32 * 1024));
  CHECK(stack_of({.name = "tiny", .stack_bytes = 1}) >= 16 * 1024);  // PTHREAD_STACK_MIN
}

TEST_CASE("setup_realtime_process bounds the malloc arenas and says so", "[platform][memory]") {
  const auto bounded = setup_realtime_process(
      {.lock_memory = false, .prefault_heap_bytes = 0, .malloc_arena_max = 2});
#if defined(__SANITIZE_ADDRESS__)
  // ASan replaces malloc: mallopt(M_ARENA_MAX) has no arenas to bound and fails, and says so.
  CHECK(bounded.malloc_arena_max == 0);
  CHECK(bounded.describe().find("malloc arenas: glibc default") != std::string::npos);
#else
  CHECK(bounded.malloc_arena_max == 2);
  CHECK(bounded.describe().find("malloc arenas: at most 2") != std::string::npos);
#endif
  const auto untouched = setup_realtime_process(
      {.lock_memory = false, .prefault_heap_bytes = 0, .malloc_arena_max = 0});
  CHECK(untouched.malloc_arena_max == 0);
  CHECK(untouched.describe().find("malloc arenas: glibc default") != std::string::npos);
  // The default bounds them to one: the prefaulted main heap serves every thread.
  STATIC_REQUIRE(RealtimeSetupOptions{}.malloc_arena_max == 1);
  STATIC_REQUIRE(RealtimeSetupOptions{}.prefault_heap_bytes == 4 * 1024 * 1024);
}

TEST_CASE("bound_malloc_arenas sets the bound alone and returns it", "[platform][memory]") {
  // Nothing to do, nothing done: 0 and a negative bound leave glibc's default.
  CHECK(bound_malloc_arenas(0) == 0);
  CHECK(bound_malloc_arenas(-3) == 0);
#if defined(__SANITIZE_ADDRESS__)
  CHECK(bound_malloc_arenas(2) == 0);  // ASan's malloc has no arenas: refused, and said so
#else
  CHECK(bound_malloc_arenas(2) == 2);
#endif
}
