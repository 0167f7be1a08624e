# One place that says how a vigil target is built (cactus-rt's setup_cactus_rt_target_options):
# warnings, sanitizers and clang-tidy are PRIVATE to vigil's own targets.
include(GNUInstallDirs)

set(VIGIL_MODULE_TARGETS "" CACHE INTERNAL "")

function(vigil_target_options target)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align
    -Wimplicit-fallthrough)
  if(VIGIL_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(VIGIL_CLANG_TIDY)
    vigil_clang_tidy_command(command)
    set_target_properties(${target} PROPERTIES CXX_CLANG_TIDY "${command}")
  endif()
endfunction()

# clang-tidy (the tidy preset): the checks are in .clang-tidy at the top of the tree; every check
# enabled there is an error. The tool parses the compile commands GCC gets, with two additions when
# vigil::expected is std::expected (C++23): clang spells the standard -std=gnu++2b, and GCC 12's
# <expected> is only declared for compilers announcing C++20 concepts in full (__cpp_concepts
# 202002L), which clang 16 implements (conditionally trivial special members, P0848) but does not
# announce; clang-tidy 16 or newer is therefore required then (clang 14 cannot parse it).
#
# vigil_clang_tidy_command(<out>) sets <out> to the CXX_CLANG_TIDY command. Called when the first target is made (after the
# top-level CMakeLists.txt has chosen VIGIL_EXPECTED_TL).
function(vigil_clang_tidy_command out)
  find_program(VIGIL_CLANG_TIDY_EXE NAMES clang-tidy-16 clang-tidy-17 clang-tidy-18 clang-tidy-19
                                          clang-tidy-14 clang-tidy REQUIRED)
  execute_process(COMMAND ${VIGIL_CLANG_TIDY_EXE} --version OUTPUT_VARIABLE _tidy_version)
  string(REGEX MATCH "version ([0-9]+)" _tidy_version "${_tidy_version}")
  set(_tidy_major "${CMAKE_MATCH_1}")
  set(command "${VIGIL_CLANG_TIDY_EXE}")
  if(NOT VIGIL_EXPECTED_TL)
    if(_tidy_major LESS 16)
      message(FATAL_ERROR "${VIGIL_CLANG_TIDY_EXE} is version ${_tidy_major}: parsing GCC 12's "
                          "std::expected needs clang-tidy 16 or newer (scripts/setup.sh installs "
                          "clang-tidy-16)")
    endif()
    list(APPEND command --extra-arg=-std=gnu++2b --extra-arg=-U__cpp_concepts
         --extra-arg=-D__cpp_concepts=202002L)
  endif()
  set(${out} "${command}" PARENT_SCOPE)
endfunction()

# Sanitizers apply to everything compiled in this build tree (libraries, tests, apps) so that
# instrumented and non-instrumented code never mix.
if(VIGIL_SANITIZE)
  add_compile_options(-fsanitize=${VIGIL_SANITIZE} -fno-omit-frame-pointer -g)
  add_link_options(-fsanitize=${VIGIL_SANITIZE})
  # Lets tests skip what sanitizers make impossible (their malloc and mlockall interceptors).
  add_compile_definitions(VIGIL_SANITIZER_BUILD=1)
  if(VIGIL_SANITIZE MATCHES "undefined")
    add_compile_options(-fno-sanitize-recover=undefined)
  endif()
endif()

# vigil_add_module(NAME name SOURCES ... [DEPS ...] [PRIVATE_DEPS ...])
# Creates vigil_<name> with alias vigil::<name>; headers live in include/vigil/<name>/.
function(vigil_add_module)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  set(target vigil_${ARG_NAME})
  if(ARG_SOURCES)
    add_library(${target} STATIC ${ARG_SOURCES})
    target_include_directories(${target} PUBLIC
      $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
      $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>
      PRIVATE ${PROJECT_SOURCE_DIR}/src)
    target_link_libraries(${target} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
    set_target_properties(${target} PROPERTIES
      OUTPUT_NAME vigil_${ARG_NAME}
      POSITION_INDEPENDENT_CODE ON)
    vigil_target_options(${target})
  else()
    add_library(${target} INTERFACE)
    target_include_directories(${target} INTERFACE
      $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
      $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
    target_link_libraries(${target} INTERFACE ${ARG_DEPS})
  endif()
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_NAME})
  add_library(vigil::${ARG_NAME} ALIAS ${target})
  set(VIGIL_MODULE_TARGETS ${VIGIL_MODULE_TARGETS} ${target} CACHE INTERNAL "")
endfunction()
