// Compile-time filtering: this file is compiled with VIGIL_LOG_LEVEL = WARN.
#define VIGIL_LOG_LEVEL VIGIL_LOG_LEVEL_WARN
#include <catch2/catch.hpp>

#include "log_support.hpp"
#include "vigil/log/log.hpp"

using namespace vigil;
using vigil::test::LogBench;

namespace {
int evaluated = 0;
int count_evaluation() { return ++evaluated; }
}  // namespace

TEST_CASE("Calls below VIGIL_LOG_LEVEL are compiled out, arguments not evaluated", "[log][level]") {
  LogBench<> c("compiled_out");
  log::set_level("compiled_out", log::Level::Debug);  // the run-time level lets everything in
  evaluated = 0;
  VIGIL_LOG_DEBUG("debug {}", count_evaluation());
  VIGIL_LOG_INFO("info {}", count_evaluation());
  CHECK(evaluated == 0);
  CHECK(c.records().empty());
  VIGIL_LOG_WARN("warn {}", count_evaluation());
  VIGIL_LOG_ERROR("error {}", count_evaluation());
  CHECK(evaluated == 2);
  CHECK(c.records().size() == 2);
  log::reset_level("compiled_out");
}
