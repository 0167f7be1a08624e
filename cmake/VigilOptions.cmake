# Options. Defaults follow PROJECT_IS_TOP_LEVEL, so that vigil used through add_subdirectory()
# builds only its libraries (fmt's FMT_MASTER_PROJECT habit).
option(VIGIL_BUILD_TESTS "Build the Catch2 test suite" ${PROJECT_IS_TOP_LEVEL})
option(VIGIL_BUILD_BENCHES "Build the Google Benchmark benchmarks" ${PROJECT_IS_TOP_LEVEL})
option(VIGIL_BUILD_EXAMPLES "Build the examples" ${PROJECT_IS_TOP_LEVEL})
option(VIGIL_BUILD_APPS "Build the vigil command-line tool" ON)
option(VIGIL_INSTALL "Generate the install target" ${PROJECT_IS_TOP_LEVEL})
option(VIGIL_WERROR "Treat compiler warnings as errors" OFF)
option(VIGIL_CLANG_TIDY "Run clang-tidy on vigil's own targets" OFF)
set(VIGIL_SANITIZE "" CACHE STRING "Sanitizers for vigil's targets and tests: '', 'address,undefined' or 'thread'")
set_property(CACHE VIGIL_SANITIZE PROPERTY STRINGS "" "address,undefined" "thread")
set(VIGIL_TEST_DISCOVERY "build" CACHE STRING
  "How CTest learns the Catch2 test cases: build (run each test binary after linking) or sources (read the TEST_CASEs at configure time, for binaries that cannot run here)")
set_property(CACHE VIGIL_TEST_DISCOVERY PROPERTY STRINGS build sources)
if(NOT VIGIL_TEST_DISCOVERY MATCHES "^(build|sources)$")
  message(FATAL_ERROR "VIGIL_TEST_DISCOVERY='${VIGIL_TEST_DISCOVERY}' is not one of: build sources")
endif()
set(VIGIL_EXPECTED "auto" CACHE STRING "vigil::expected backend: auto (tl if found), tl, std")
set_property(CACHE VIGIL_EXPECTED PROPERTY STRINGS auto tl std)

if(PROJECT_IS_TOP_LEVEL AND NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
  set(CMAKE_BUILD_TYPE RelWithDebInfo CACHE STRING "Build type" FORCE)
endif()
set(CMAKE_EXPORT_COMPILE_COMMANDS ON)

# ccache, when installed, for every compile of this tree (scripts/setup.sh installs it). Builds of
# several checkouts of the same sources (a CI copy, git worktrees) then reuse each other's objects.
option(VIGIL_CCACHE "Compile through ccache when it is installed" ON)
if(VIGIL_CCACHE AND NOT CMAKE_CXX_COMPILER_LAUNCHER)
  find_program(VIGIL_CCACHE_EXE ccache)
  if(VIGIL_CCACHE_EXE)
    set(CMAKE_CXX_COMPILER_LAUNCHER "${VIGIL_CCACHE_EXE}")
  endif()
endif()
