// platform::initialize(): the start of the platform's real-time core (Cobalt: libcobalt's
// xenomai_init(), after the program's own command line; Linux: nothing to start).
#include <catch2/catch.hpp>
#include <cerrno>
#include <string>
#include <thread>

#include "vigil/build_config.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/platform/process.hpp"

using namespace vigil::platform;

namespace {
constexpr bool kCobalt = VIGIL_PLATFORM_COBALT != 0;
}

TEST_CASE("initialize starts the real-time core once and leaves the program's arguments alone",
          "[platform][init]") {
  // Catch2 runs test cases on the main thread: the one thread allowed to start Cobalt.
  REQUIRE(initialize().has_value());
  CHECK(initialized());
  CHECK(initialize().has_value());  // idempotent

  // Xenomai's own options in a program's arguments: Linux reads nothing; on Cobalt the core
  // already runs, so they cannot be applied and the call says so. Either way argv is untouched.
  std::string a0 = "prog";
  std::string a1 = "--version";
  std::string a2 = "--cpu-affinity=0";
  char* args[] = {a0.data(), a1.data(), a2.data(), nullptr};
  int argc = 3;
  char** argv = args;
  const auto r = initialize(argc, argv);
  if (kCobalt) {
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == EALREADY);
    CHECK(r.error().message.find("already initialised") != std::string::npos);
  } else {
    CHECK(r.has_value());
  }
  CHECK(argc == 3);
  CHECK(argv == args);
  CHECK(std::string(argv[1]) == "--version");
  CHECK(std::string(argv[2]) == "--cpu-affinity=0");
}

TEST_CASE("initialize from another thread succeeds once the core runs", "[platform][init]") {
  REQUIRE(initialize().has_value());
  bool ok = false;
  bool seen = false;
  std::thread t([&] {
    ok = initialize().has_value();
    seen = initialized();
  });
  t.join();
  CHECK(ok);
  CHECK(seen);
}

TEST_CASE("setup_realtime_process starts the core from the main thread", "[platform][init]") {
  const auto report = setup_realtime_process({.lock_memory = false,
                                              .prefault_stack_bytes = 0,
                                              .prefault_heap_bytes = 0,
                                              .request_zero_cpu_latency = false});
  CHECK(report.core_error.empty());
  CHECK(report.describe().find("real-time core") == std::string::npos);
  CHECK(initialized());
}
