# Compiles one snippet with -fsyntax-only and checks the result (see CMakeLists.txt).
#   cmake -DCOMPILER=<c++> -DCOMPILER_ID=<GNU|Clang|...> -DSOURCE=<snippet.cpp>
#         -DFLAGS_FILE=<flags-<config>.cmake> [-DPCH_HEADER=<header>]
#         [-DMODE=pass|fail|pch] [-DEXPECT=<text>] -P run_compile.cmake
# The snippet says what it expects in comment lines: `// must compile`, or one or more
# `// expect: <text>` / `// expect-<CompilerId>: <text>` (must fail, printing every <text>).
# MODE and EXPECT override the snippet (they let the suite check the harness itself).
# MODE=pch precompiles PCH_HEADER (GCC only; the suite's fixture) and never fails: without a
# usable <header>.gch, `-include <header>` reads the header itself and the results are the same.
cmake_minimum_required(VERSION 3.25)

if(MODE STREQUAL "pch")
  set(SOURCE "${PCH_HEADER}")
endif()
foreach(var COMPILER SOURCE FLAGS_FILE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run_compile.cmake: -D${var}=... is required")
  endif()
endforeach()
include(${FLAGS_FILE})

# --- the command line: the library's standard, definitions, include directories and options ----
set(args ${CF_STD_FLAG})
list(REMOVE_DUPLICATES CF_DEFINES)
list(REMOVE_DUPLICATES CF_INCLUDES)
foreach(def IN LISTS CF_DEFINES)
  list(APPEND args "-D${def}")
endforeach()
foreach(dir IN LISTS CF_INCLUDES)
  if(dir STREQUAL "" OR dir IN_LIST CF_IMPLICIT_INCLUDES)
    continue()  # e.g. Boost's /usr/include: -I would break libstdc++'s #include_next
  endif()
  # The project's own directories with -I; dependencies' as system headers, as CMake does for
  # imported targets (their warnings are not ours).
  set(flag -isystem "${dir}")
  foreach(own IN LISTS CF_PROJECT_DIRS)
    cmake_path(IS_PREFIX own "${dir}" NORMALIZE is_own)
    if(is_own)
      set(flag "-I${dir}")
    endif()
  endforeach()
  list(APPEND args ${flag})
endforeach()
foreach(opt IN LISTS CF_OPTIONS)
  if(opt MATCHES "^SHELL:(.*)$")
    separate_arguments(shell_args UNIX_COMMAND "${CMAKE_MATCH_1}")
    list(APPEND args ${shell_args})
  elseif(NOT opt STREQUAL "")
    list(APPEND args "${opt}")
  endif()
endforeach()

# --- the precompiled header (the fixture), rebuilt on every run: GCC does not notice that a
# header inside a .gch changed, so a stale one must never survive ----------------------------------
if(MODE STREQUAL "pch")
  file(REMOVE "${PCH_HEADER}.gch")
  if(NOT COMPILER_ID STREQUAL "GNU")
    message(STATUS "no precompiled header with ${COMPILER_ID}: the snippets read the headers")
    return()
  endif()
  execute_process(
    COMMAND ${COMPILER} ${args} -x c++-header "${PCH_HEADER}" -o "${PCH_HEADER}.gch"
    RESULT_VARIABLE rc
    OUTPUT_VARIABLE out
    ERROR_VARIABLE out)
  if(NOT rc EQUAL 0)
    file(REMOVE "${PCH_HEADER}.gch")
    message(NOTICE "${out}")
    message(STATUS "no precompiled header (the compiler failed): the snippets read the headers")
  else()
    message(STATUS "precompiled ${PCH_HEADER}.gch")
  endif()
  return()
endif()

# --- what the snippet expects --------------------------------------------------------------------
file(READ ${SOURCE} content)
# Keep the characters that CMake's lists treat specially out of the way while splitting lines.
string(REPLACE "\\" "<backslash>" content "${content}")
string(REPLACE "[" "<lbracket>" content "${content}")
string(REPLACE "]" "<rbracket>" content "${content}")
string(REPLACE ";" "<semicolon>" content "${content}")
string(REPLACE "\n" ";" lines "${content}")
set(mode "")
set(expected "")
foreach(line IN LISTS lines)
  if(line MATCHES "^// must compile[ \t]*$")
    set(mode pass)
  elseif(line MATCHES "^// expect(-([A-Za-z]+))?: *(.*[^ \t])[ \t]*$")
    set(id "${CMAKE_MATCH_2}")
    set(text "${CMAKE_MATCH_3}")
    set(mode fail)
    if(id STREQUAL "" OR id STREQUAL "${COMPILER_ID}")
      list(APPEND expected "${text}")
    endif()
  endif()
endforeach()
if(DEFINED MODE)
  set(mode "${MODE}")
endif()
if(DEFINED EXPECT)
  string(REPLACE ";" "<semicolon>" expected "${EXPECT}")
endif()
if(NOT mode MATCHES "^(pass|fail)$")
  message(FATAL_ERROR "${SOURCE}: no `// must compile` or `// expect: <text>` line")
endif()
if(mode STREQUAL "fail" AND NOT expected)
  message(FATAL_ERROR "${SOURCE}: must fail, but no expected text for compiler ${COMPILER_ID}")
endif()

if(PCH_HEADER AND EXISTS "${PCH_HEADER}")
  list(APPEND args -include "${PCH_HEADER}")
endif()
list(APPEND args -fsyntax-only -fdiagnostics-color=never "${SOURCE}")

# LC_ALL=C: plain ASCII quotes in GCC's messages, whatever the caller's locale.
execute_process(
  COMMAND ${CMAKE_COMMAND} -E env LC_ALL=C ${COMPILER} ${args}
  RESULT_VARIABLE rc
  OUTPUT_VARIABLE out
  ERROR_VARIABLE out)
list(JOIN args " " shown)
# Printed as is (message(NOTICE) does not rewrap): ctest shows it on failure or with -V.
message(NOTICE "command: ${COMPILER} ${shown}\nexit code: ${rc}\n"
               "--- compiler output ---\n${out}--- end of compiler output ---")

# --- verdict -------------------------------------------------------------------------------------
if(mode STREQUAL "pass")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "FAIL: ${SOURCE} must compile, but the compiler failed.")
  endif()
  message(STATUS "ok: compiles")
  return()
endif()
if(rc EQUAL 0)
  message(FATAL_ERROR "FAIL: ${SOURCE} must not compile, but it compiled.")
endif()
if(NOT rc MATCHES "^[0-9]+$")
  # Not an exit code: the compiler could not be run at all.
  message(FATAL_ERROR "FAIL: could not run the compiler: ${rc}")
endif()
set(missing "")
foreach(text IN LISTS expected)
  string(REPLACE "<semicolon>" ";" text "${text}")
  string(REPLACE "<lbracket>" "[" text "${text}")
  string(REPLACE "<rbracket>" "]" text "${text}")
  string(REPLACE "<backslash>" "\\" text "${text}")
  string(FIND "${out}" "${text}" at)
  if(at EQUAL -1)
    string(APPEND missing "\n  ${text}")
  endif()
endforeach()
if(missing)
  message(FATAL_ERROR
    "FAIL: ${SOURCE} failed to compile as it must, but the output lacks:${missing}")
endif()
list(LENGTH expected n)
message(STATUS "ok: fails with the ${n} expected text(s)")
