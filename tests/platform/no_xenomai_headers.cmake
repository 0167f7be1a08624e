# Proves that Xenomai stays inside src/platform/cobalt/ (STYLE.md rule 4 and 11;
# docs/design/platform.md). Run with `cmake -P`; registered by tests/platform/CMakeLists.txt.
#
#   -DVIGIL_SOURCE_DIR=<repo>          scan every file under <repo>/include and <repo>/src, except
#                                      src/platform/cobalt/, for an #include of a Xenomai header
#                                      (cobalt/..., xenomai/..., alchemy/..., boilerplate/..., the
#                                      other Xenomai 3 include folders, <xeno_config.h>); fails
#                                      naming each file:line.
#   -DVIGIL_COMPILE_COMMANDS=<file>    check a (Linux) build's compile_commands.json: no file of
#                                      src/platform/cobalt/, no include path containing "cobalt",
#                                      no __COBALT__ / __COBALT_WRAP__ definition. The build
#                                      directory (the file's folder) and -DVIGIL_SOURCE_ROOT=<repo>
#                                      are masked first, so that their own names do not count.
#   -DVIGIL_SELF_TEST_DIR=<dir>        sanity check of the scanner itself: plants a leak in a
#                                      scratch tree under <dir> and fails unless the scan finds
#                                      exactly it, at the right line, and ignores the Cobalt folder.
cmake_minimum_required(VERSION 3.25)

# Top-level folders of an installed Xenomai 3 include directory, plus its configuration header.
set(_xeno_dirs "cobalt|xenomai|alchemy|boilerplate|copperplate|rtdm|trank|psos|vxworks|smokey")
set(_include_re "#[ \t]*include[ \t]*[<\"]((${_xeno_dirs})/[^>\"]*|xeno_config\\.h)[>\"]")

# Appends "file:line: text" to the list named by `out_var` for each Xenomai include in `file`.
function(vigil_scan_file file display out_var)
  # Cheap filter first: most files have no match at all.
  file(STRINGS "${file}" hits REGEX "${_include_re}")
  if(NOT hits)
    return()
  endif()
  file(READ "${file}" content)
  set(found ${${out_var}})
  set(consumed 0)
  set(rest "${content}")
  while(TRUE)
    string(REGEX MATCH "(^|\n)[ \t]*${_include_re}[^\n]*" m "${rest}")
    if(m STREQUAL "")
      break()
    endif()
    string(FIND "${rest}" "${m}" pos)
    string(LENGTH "${m}" len)
    math(EXPR at "${consumed} + ${pos}")
    string(SUBSTRING "${content}" 0 ${at} before)
    string(REGEX MATCHALL "\n" newlines "${before}")
    list(LENGTH newlines line)
    string(REGEX REPLACE "^\n" "" text "${m}")
    if(m MATCHES "^\n")
      math(EXPR line "${line} + 2")
    else()
      math(EXPR line "${line} + 1")
    endif()
    string(STRIP "${text}" text)
    list(APPEND found "${display}:${line}: ${text}")
    math(EXPR skip "${pos} + ${len}")
    math(EXPR consumed "${consumed} + ${skip}")
    string(SUBSTRING "${rest}" ${skip} -1 rest)
  endwhile()
  set(${out_var} "${found}" PARENT_SCOPE)
endfunction()

# Scans <root>/include and <root>/src except <root>/src/platform/cobalt; result in `out_var`.
function(vigil_scan_tree root out_var)
  file(GLOB_RECURSE files LIST_DIRECTORIES false "${root}/include/*" "${root}/src/*")
  list(SORT files)
  set(found "")
  set(count 0)
  foreach(f IN LISTS files)
    file(RELATIVE_PATH rel "${root}" "${f}")
    if(rel MATCHES "^src/platform/cobalt/")
      continue()
    endif()
    math(EXPR count "${count} + 1")
    vigil_scan_file("${f}" "${rel}" found)
  endforeach()
  set(${out_var} "${found}" PARENT_SCOPE)
  set(${out_var}_COUNT ${count} PARENT_SCOPE)
endfunction()

function(vigil_report_and_fail title findings)
  string(REPLACE ";" "\n  " lines "${findings}")
  message(FATAL_ERROR "${title}\n  ${lines}")
endfunction()

set(_did_something FALSE)

if(DEFINED VIGIL_SOURCE_DIR)
  set(_did_something TRUE)
  if(NOT IS_DIRECTORY "${VIGIL_SOURCE_DIR}/include" OR NOT IS_DIRECTORY "${VIGIL_SOURCE_DIR}/src")
    message(FATAL_ERROR "VIGIL_SOURCE_DIR='${VIGIL_SOURCE_DIR}' has no include/ and src/")
  endif()
  vigil_scan_tree("${VIGIL_SOURCE_DIR}" findings)
  if(findings)
    vigil_report_and_fail(
      "Xenomai headers outside src/platform/cobalt/ (keep them in the Cobalt implementation):"
      "${findings}")
  endif()
  message(STATUS "no Xenomai header included in ${findings_COUNT} files of include/ and src/ "
                 "(src/platform/cobalt/ excepted)")
endif()

if(DEFINED VIGIL_SELF_TEST_DIR)
  set(_did_something TRUE)
  set(t "${VIGIL_SELF_TEST_DIR}/no_xenomai_headers_self_test")
  file(REMOVE_RECURSE "${t}")
  file(WRITE "${t}/include/vigil/clean.hpp" "#pragma once\n#include <pthread.h>\n// cobalt/x.h\n")
  file(WRITE "${t}/include/vigil/leak.hpp"
       "#pragma once\n#include <vector>; [unbalanced\n\n  #  include \"cobalt/sys/cobalt.h\"\n")
  file(WRITE "${t}/src/x/leak.cpp" "int x;\n#include <xeno_config.h>\n")
  file(WRITE "${t}/src/platform/cobalt/ok.cpp" "#include <cobalt/sys/cobalt.h>\n")
  vigil_scan_tree("${t}" findings)
  set(expected "include/vigil/leak.hpp:4: #  include \"cobalt/sys/cobalt.h\""
               "src/x/leak.cpp:2: #include <xeno_config.h>")
  if(NOT findings STREQUAL expected)
    vigil_report_and_fail("scanner self-test: expected\n  ${expected}\nbut found:" "${findings}")
  endif()
  file(REMOVE_RECURSE "${t}")
  message(STATUS "scanner self-test passed: both planted includes found, Cobalt folder ignored")
endif()

if(DEFINED VIGIL_COMPILE_COMMANDS)
  set(_did_something TRUE)
  if(NOT EXISTS "${VIGIL_COMPILE_COMMANDS}")
    message(FATAL_ERROR "${VIGIL_COMPILE_COMMANDS} does not exist (CMAKE_EXPORT_COMPILE_COMMANDS)")
  endif()
  file(READ "${VIGIL_COMPILE_COMMANDS}" json)
  get_filename_component(_build_dir "${VIGIL_COMPILE_COMMANDS}" DIRECTORY)
  string(JSON n LENGTH "${json}")
  set(findings "")
  if(n GREATER 0)
    math(EXPR last "${n} - 1")
    foreach(i RANGE ${last})
      string(JSON file GET "${json}" ${i} file)
      string(JSON command ERROR_VARIABLE no_command GET "${json}" ${i} command)
      if(no_command)
        # Generators that write "arguments" (a JSON array) instead of "command".
        string(JSON command GET "${json}" ${i} arguments)
      endif()
      if(file MATCHES "/src/platform/cobalt/")
        list(APPEND findings "${file}: a Cobalt source is compiled")
      endif()
      # The project's own folders may have any name (build/h-cobalt, /home/cobalt/vigil): only the
      # part of a path outside them counts.
      string(REPLACE "${_build_dir}" "<build>" command "${command}")
      if(DEFINED VIGIL_SOURCE_ROOT)
        string(REPLACE "${VIGIL_SOURCE_ROOT}" "<source>" command "${command}")
      endif()
      if(command MATCHES "-(I|isystem|iquote|idirafter)[ \"]*([^ \"]*cobalt[^ \"]*)")
        list(APPEND findings "${file}: include path ${CMAKE_MATCH_2}")
      endif()
      if(command MATCHES "__COBALT(_WRAP)?__")
        list(APPEND findings "${file}: defines ${CMAKE_MATCH_0}")
      endif()
    endforeach()
  endif()
  if(findings)
    vigil_report_and_fail("Xenomai compile flags in the build of ${VIGIL_COMPILE_COMMANDS}:"
                          "${findings}")
  endif()
  message(STATUS "${n} compile commands, none with a Cobalt include path or __COBALT__")
endif()

if(NOT _did_something)
  message(FATAL_ERROR "pass -DVIGIL_SOURCE_DIR, -DVIGIL_COMPILE_COMMANDS or -DVIGIL_SELF_TEST_DIR")
endif()
