# FindXenomai: locates a Xenomai 3 Cobalt installation through xeno-config. Installed with vigil
# (lib/cmake/vigil/) and used by vigil-config.cmake when vigil was built for Cobalt, so a user's
# project needs only find_package(vigil) and XENOMAI_ROOT.
#
# Input: XENOMAI_ROOT (CMake or environment variable: prefix of the install, xeno-config is in
#   ${XENOMAI_ROOT}/bin), else xeno-config on the PATH, else Xenomai_DEFAULT_ROOT (set by
#   vigil-config.cmake to the prefix vigil was built against).
# Output: Xenomai_FOUND, Xenomai_VERSION, XENO_CONFIG, Xenomai_LIBRARY_DIRS (the -L folders of
#   the link flags: where libcobalt.so is, for a build RPATH), and imported targets
#   Xenomai::cobalt      - compile flags of `xeno-config --cobalt --cflags`: include directories
#                          (SYSTEM for consumers, so Xenomai's headers raise no warnings in ours),
#                          definitions (__COBALT__, _GNU_SOURCE, _REENTRANT) and options. For the
#                          platform implementation only (src/platform/cobalt/): libcobalt's
#                          include directory shadows <pthread.h>, <time.h>, ...
#   Xenomai::cobalt_link - link flags of `xeno-config --cobalt --ldflags --no-auto-init` for
#                          executables, shared and module libraries (libcobalt, libmodechk's --wrap
#                          of malloc/free), nothing for static libraries, and a RUNPATH entry for
#                          Xenomai's library folder (libcobalt.so and libmodechk.so are found there
#                          by the built and by the installed binaries). No automatic start-up
#                          (bootstrap.o, --wrap=main): it would read the command line before main()
#                          and act on --help, --version, --verbose, ... itself; vigil starts
#                          libcobalt with vigil::platform::initialize() (src/platform/cobalt/
#                          core.cpp), after the program has parsed its own command line.
#                          Deliberately not `--posix`: libcobalt's POSIX --wrap list
#                          would turn every pthread_mutex_lock of the link (std::mutex included)
#                          into a Cobalt mutex while std::condition_variable and std::shared_mutex
#                          stay glibc's (docs/design/platform.md, "One kind of thread, one kind
#                          of lock").
# Tested with Xenomai v3.2.7 built from source (docs/design/platform.md, "Cobalt: what was checked").
find_program(XENO_CONFIG xeno-config
  HINTS ${XENOMAI_ROOT}/bin $ENV{XENOMAI_ROOT}/bin
  PATHS ${Xenomai_DEFAULT_ROOT}/bin)
if(XENO_CONFIG)
  execute_process(COMMAND ${XENO_CONFIG} --version OUTPUT_VARIABLE Xenomai_VERSION
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --core OUTPUT_VARIABLE Xenomai_CORE
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --cobalt --cflags OUTPUT_VARIABLE _xeno_cflags
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --cobalt --ldflags --no-auto-init
                  OUTPUT_VARIABLE _xeno_ldflags OUTPUT_STRIP_TRAILING_WHITESPACE)
  separate_arguments(_xeno_cflags UNIX_COMMAND "${_xeno_cflags}")
  separate_arguments(_xeno_ldflags UNIX_COMMAND "${_xeno_ldflags}")
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
  set(Xenomai_LIBRARY_DIRS "")
  set(_xeno_rpath "")
  foreach(_flag IN LISTS _xeno_ldflags)
    if(_flag MATCHES "^-L(.+)$")
      list(APPEND Xenomai_LIBRARY_DIRS "${CMAKE_MATCH_1}")
      list(APPEND _xeno_rpath "LINKER:-rpath,${CMAKE_MATCH_1}")
    elseif(_flag MATCHES "bootstrap|--wrap=main")
      # xeno-config ignored --no-auto-init (not a 3.x xeno-config?): refuse rather than link a
      # start-up that reads the program's command line.
      message(FATAL_ERROR "${XENO_CONFIG} --cobalt --ldflags --no-auto-init still gives '${_flag}'")
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
  add_library(Xenomai::cobalt_link INTERFACE IMPORTED)
  # Executables, shared and module libraries: the same flags (no bootstrap object either way).
  # The RUNPATH entry stays in installed binaries: CMake's install step replaces only the build
  # RPATH it computed itself.
  set(_is_linked "$<IN_LIST:$<TARGET_PROPERTY:TYPE>,EXECUTABLE;SHARED_LIBRARY;MODULE_LIBRARY>")
  set_target_properties(Xenomai::cobalt_link PROPERTIES INTERFACE_LINK_OPTIONS
    "$<${_is_linked}:${_xeno_ldflags};${_xeno_rpath}>")
endif()
