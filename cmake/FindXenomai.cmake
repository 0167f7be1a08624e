# FindXenomai: locates a Xenomai 3 Cobalt installation through xeno-config.
# Input: XENOMAI_ROOT (CMake or environment variable: prefix of the install, xeno-config is in
#   ${XENOMAI_ROOT}/bin), or xeno-config on the PATH. Output: Xenomai_FOUND, Xenomai_VERSION,
#   XENO_CONFIG, and imported targets
#   Xenomai::cobalt    - compile flags of `xeno-config --posix --cflags`: include directories
#                        (SYSTEM for consumers, so Xenomai's headers raise no warnings in ours),
#                        definitions (__COBALT__, __COBALT_WRAP__, _GNU_SOURCE, _REENTRANT) and
#                        options. For the platform implementation only (src/platform/cobalt/):
#                        libcobalt's include directory shadows <pthread.h>, <time.h>, ...
#   Xenomai::posix_exe - link flags: `xeno-config --posix --ldflags` for executables (libcobalt,
#                        the --wrap lists, bootstrap.o that runs xenomai_init() before main());
#                        `... --auto-init-solib` (bootstrap-pic.o, no --wrap=main) when the
#                        consumer is a shared or module library. Nothing for static libraries.
# Tested with Xenomai v3.2.7 built from source (docs/design/platform.md, "Cobalt: what was checked").
find_program(XENO_CONFIG xeno-config HINTS ${XENOMAI_ROOT}/bin $ENV{XENOMAI_ROOT}/bin)
if(XENO_CONFIG)
  execute_process(COMMAND ${XENO_CONFIG} --version OUTPUT_VARIABLE Xenomai_VERSION
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --core OUTPUT_VARIABLE Xenomai_CORE
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --posix --cflags OUTPUT_VARIABLE _xeno_cflags
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --posix --ldflags OUTPUT_VARIABLE _xeno_ldflags
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --posix --ldflags --auto-init-solib
                  OUTPUT_VARIABLE _xeno_solib_ldflags OUTPUT_STRIP_TRAILING_WHITESPACE)
  separate_arguments(_xeno_cflags UNIX_COMMAND "${_xeno_cflags}")
  separate_arguments(_xeno_ldflags UNIX_COMMAND "${_xeno_ldflags}")
  separate_arguments(_xeno_solib_ldflags UNIX_COMMAND "${_xeno_solib_ldflags}")
  set(Xenomai_INCLUDE_DIRS "")
  set(Xenomai_DEFINITIONS "")
  set(Xenomai_COMPILE_OPTIONS "")
  foreach(_flag IN LISTS _xeno_cflags)
    if(_flag MATCHES "^-I(.+)$")
      list(APPEND Xenomai_INCLUDE_DIRS "${CMAKE_MATCH_1}")
    elseif(_flag MATCHES "^-D(.+)$")
      list(APPEND Xenomai_DEFINITIONS "${CMAKE_MATCH_1}")
    else()
      list(APPEND Xenomai_COMPILE_OPTIONS "${_flag}")
    endif()
  endforeach()
endif()
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(Xenomai
  REQUIRED_VARS XENO_CONFIG Xenomai_INCLUDE_DIRS VERSION_VAR Xenomai_VERSION)
if(Xenomai_FOUND AND NOT Xenomai_CORE STREQUAL "cobalt")
  message(FATAL_ERROR "${XENO_CONFIG} is for the '${Xenomai_CORE}' core; vigil needs cobalt")
endif()
if(Xenomai_FOUND AND NOT TARGET Xenomai::cobalt)
  add_library(Xenomai::cobalt INTERFACE IMPORTED)
  set_target_properties(Xenomai::cobalt PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${Xenomai_INCLUDE_DIRS}"
    INTERFACE_COMPILE_DEFINITIONS "${Xenomai_DEFINITIONS}"
    INTERFACE_COMPILE_OPTIONS "${Xenomai_COMPILE_OPTIONS}")
  add_library(Xenomai::posix_exe INTERFACE IMPORTED)
  set(_is_exe "$<STREQUAL:$<TARGET_PROPERTY:TYPE>,EXECUTABLE>")
  set(_is_solib "$<IN_LIST:$<TARGET_PROPERTY:TYPE>,SHARED_LIBRARY;MODULE_LIBRARY>")
  set_target_properties(Xenomai::posix_exe PROPERTIES INTERFACE_LINK_OPTIONS
    "$<${_is_exe}:${_xeno_ldflags}>;$<${_is_solib}:${_xeno_solib_ldflags}>")
endif()
