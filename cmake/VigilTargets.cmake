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
    find_program(VIGIL_CLANG_TIDY_EXE NAMES clang-tidy-14 clang-tidy REQUIRED)
    set_target_properties(${target} PROPERTIES CXX_CLANG_TIDY "${VIGIL_CLANG_TIDY_EXE}")
  endif()
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
