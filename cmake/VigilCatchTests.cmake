# Registers the Catch2 test cases of a test executable with CTest from its sources, at configure
# time, without running the executable: for builds whose binaries cannot run on the build machine
# (VIGIL_TEST_DISCOVERY=sources, the cobalt preset: a Cobalt test binary stops when it starts
# Cobalt on a kernel without Cobalt). Each TEST_CASE("name", "[tags]") becomes one CTest test named `name`,
# with the same command line catch_discover_tests (Catch2's CatchAddTests.cmake) writes:
# `<exe> <name with , [ ] escaped>`, in the same working directory, with the given properties.
# So both modes list the same tests under the same names; tests/CMakeLists.txt chooses one.
#
# Only what this repository uses is understood: TEST_CASE whose first argument is one string
# literal without escapes. Anything else (a TEST_CASE with another form, SCENARIO,
# TEMPLATE_TEST_CASE, TEST_CASE_METHOD) stops the configuration naming file:line, rather than
# silently registering fewer tests. Preprocessor conditions are not evaluated: a TEST_CASE under
# #if is registered whatever the condition (keep such cases under the same name in every branch,
# as tests/can/sniffer_test.cpp does for the sanitizer builds). Hidden test cases ([.] or [!hide] tags), which Catch2 does not
# list, are not registered either.

# CHECK_ONLY: read the sources and stop on what the function does not understand, but register
# nothing (the other builds call it so: a test file that only the cobalt build would refuse
# stops every configuration, not just the one nobody runs here).
#
# vigil_catch_tests_from_sources(<target> SOURCES <file>... [CHECK_ONLY]
#                                [PROPERTIES <prop> <value>...])
function(vigil_catch_tests_from_sources target)
  cmake_parse_arguments(ARG "CHECK_ONLY" "" "SOURCES;PROPERTIES" ${ARGN})
  set(ws "[ \t\r\n]*")
  set(names "")
  foreach(src IN LISTS ARG_SOURCES)
    get_filename_component(path "${src}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
    # Re-run the configuration when a test file changes, so added tests are registered.
    if(NOT ARG_CHECK_ONLY)
      set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${path}")
    endif()
    file(READ "${path}" content)
    # Unsupported Catch2 registration macros: refuse instead of undercounting.
    string(REGEX MATCH "(^|\n)[ \t]*(SCENARIO|TEMPLATE_[A-Z_]*TEST_CASE|TEST_CASE_METHOD|METHOD_AS_TEST_CASE|REGISTER_TEST_CASE|CATCH_[A-Z_]*TEST_CASE)[ \t]*\\(" bad "${content}")
    if(bad)
      string(STRIP "${bad}" bad)
      message(FATAL_ERROR "${path}: '${bad}' is not understood by vigil_catch_tests_from_sources "
                          "(cmake/VigilCatchTests.cmake); extend it or use TEST_CASE")
    endif()
    set(rest "${content}")
    while(TRUE)
      string(FIND "${rest}" "TEST_CASE(" pos)
      if(pos EQUAL -1)
        break()
      endif()
      # Line number of this occurrence, for error messages.
      string(LENGTH "${content}" total)
      string(LENGTH "${rest}" left)
      math(EXPR offset "${total} - ${left} + ${pos}")
      string(SUBSTRING "${content}" 0 ${offset} before)
      string(REGEX MATCHALL "\n" nl "${before}")
      list(LENGTH nl line)
      math(EXPR line "${line} + 1")

      string(SUBSTRING "${rest}" ${pos} -1 rest)
      # The macro must start its line (skips mentions in comments and strings).
      if(NOT before STREQUAL "" AND NOT before MATCHES "\n[ \t]*$")
        string(SUBSTRING "${rest}" 10 -1 rest)
        continue()
      endif()
      if(NOT rest MATCHES "^TEST_CASE\\(${ws}\"([^\"\\\\\n]*)\"${ws}(,${ws}\"([^\"\\\\\n]*)\"${ws})?\\)")
        message(FATAL_ERROR "${path}:${line}: TEST_CASE not understood by "
                            "vigil_catch_tests_from_sources (cmake/VigilCatchTests.cmake): the "
                            "name and tags must be plain string literals without escapes")
      endif()
      set(name "${CMAKE_MATCH_1}")
      set(tags "${CMAKE_MATCH_3}")
      string(LENGTH "${CMAKE_MATCH_0}" len)
      string(SUBSTRING "${rest}" ${len} -1 rest)
      if(name MATCHES ";")
        message(FATAL_ERROR "${path}:${line}: a test name with ';' cannot be a CTest test name")
      endif()
      if(tags MATCHES "\\[\\.|\\[!hide\\]" OR name MATCHES "^\\./")
        continue()
      endif()
      # The same name twice: alternatives under #if/#else (the preprocessor is not evaluated
      # here). Registered once; a binary that really had two would fail at start-up (Catch2
      # refuses duplicate names), so nothing is hidden.
      if(name IN_LIST names)
        continue()
      endif()
      list(APPEND names "${name}")
      if(ARG_CHECK_ONLY)
        continue()
      endif()
      # Catch2's test-spec syntax: escape the characters it parses, as CatchAddTests.cmake does.
      set(spec "${name}")
      foreach(char , [ ])
        string(REPLACE "${char}" "\\${char}" spec "${spec}")
      endforeach()
      add_test(NAME "${name}" COMMAND ${target} "${spec}"
               WORKING_DIRECTORY "${CMAKE_CURRENT_BINARY_DIR}")
      if(ARG_PROPERTIES)
        set_tests_properties("${name}" PROPERTIES ${ARG_PROPERTIES})
      endif()
    endwhile()
  endforeach()
  if(NOT names)
    message(FATAL_ERROR "${target}: no TEST_CASE found in ${ARG_SOURCES}")
  endif()
endfunction()
