#include <catch2/catch.hpp>
#include <cstdlib>
#include <memory>
#include <thread>
#include <vector>

#include "vigil/platform/rt_loss.hpp"

using namespace vigil::platform;

namespace {
// Keeps the compiler from eliding an allocation/free pair (it may, for malloc and new).
template <class T>
T* escape(T* p) {
  asm volatile("" : : "g"(p) : "memory");
  return p;
}
}  // namespace

#if defined(VIGIL_ALLOC_GUARD_DISABLED)
TEST_CASE("alloc_guard is disabled under sanitizers", "[platform][alloc_guard]") {
  WARN("skipped: sanitizers interpose malloc themselves");
  CHECK_FALSE(allocation_counting_available());
}
#else
TEST_CASE("alloc_guard counts every allocation of the calling thread", "[platform][alloc_guard]") {
  REQUIRE(allocation_counting_available());
  const auto a = thread_allocations();
  void* p = escape(std::malloc(16));
  void* q = escape(std::calloc(4, 4));
  p = escape(std::realloc(p, 64));
  void* r = nullptr;
  const int rc = posix_memalign(&r, 64, 64);
  escape(r);
  void* s = escape(std::aligned_alloc(64, 64));
  auto* n = escape(new int(1));
  auto* arr = escape(new int[10]);
  const auto b = thread_allocations();
  std::free(p);
  std::free(q);
  std::free(r);
  std::free(s);
  delete n;
  delete[] arr;
  const auto c = thread_allocations();
  CHECK(rc == 0);
  CHECK(b - a == 7);
  CHECK(c == b);  // frees are not allocations
}

TEST_CASE("alloc_guard counts per thread", "[platform][alloc_guard]") {
  const auto mine = thread_allocations();
  std::uint64_t theirs = 0;
  std::thread t([&] {
    const auto a = thread_allocations();
    std::vector<int> v(100);
    v.push_back(1);  // reallocation
    escape(v.data());
    theirs = thread_allocations() - a;
  });
  t.join();
  CHECK(theirs == 2);
  // Creating the thread allocated on this thread; the worker's allocations did not count here.
  CHECK(thread_allocations() - mine < 10);
}

TEST_CASE("alloc_guard adds nothing when no allocation happens", "[platform][alloc_guard]") {
  const auto a = thread_allocations();
  int x = 0;
  for (int i = 0; i < 1000; ++i) x += i;
  CHECK(x == 499500);
  CHECK(thread_allocations() == a);
}
#endif
