#pragma once
// Data that lives outside the repository (../shared/data, beside the checkout). A test that
// needs it starts with VIGIL_REQUIRE_SHARED_DATA(path): when the file is absent the test prints
// "skipped: ../shared/data/<relative> absent" and returns, and CTest (SKIP_REGULAR_EXPRESSION,
// set for every test by vigil_add_test) reports it as Skipped rather than passed. When the file
// is present the test runs. A plain clone with nothing beside it therefore passes.

#include <catch2/catch.hpp>
#include <filesystem>
#include <string>

namespace vigil::test {

/// ../shared/data/<relative> as seen from the source tree (VIGIL_SHARED_DATA_DIR, set by
/// tests/CMakeLists.txt).
inline std::filesystem::path shared_data(const std::string& relative) {
  return std::filesystem::path(VIGIL_SHARED_DATA_DIR) / relative;
}

}  // namespace vigil::test

/// Skips the current test (with the reason CTest recognises) when ../shared/data/<relative> is
/// absent; otherwise does nothing.
#define VIGIL_REQUIRE_SHARED_DATA(relative)                                                \
  do {                                                                                     \
    const std::filesystem::path vigil_shared_path_ = ::vigil::test::shared_data(relative); \
    if (!std::filesystem::exists(vigil_shared_path_)) {                                    \
      WARN("skipped: ../shared/data/" << (relative) << " absent (looked for "              \
                                      << vigil_shared_path_.string() << ")");              \
      return;                                                                              \
    }                                                                                      \
  } while (false)
