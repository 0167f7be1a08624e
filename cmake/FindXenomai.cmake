# FindXenomai: locates a Xenomai 3 Cobalt installation through xeno-config.
# Input: XENOMAI_ROOT (prefix of the install). Output: Xenomai_FOUND, imported targets
#   Xenomai::cobalt  - compile flags of `xeno-config --posix --cflags` (no wrapping of symbols
#                      for libraries), to be used by the platform implementation only;
#   Xenomai::posix_exe - link flags of `xeno-config --posix --ldflags`, for executables.
find_program(XENO_CONFIG xeno-config HINTS ${XENOMAI_ROOT}/bin $ENV{XENOMAI_ROOT}/bin)
if(XENO_CONFIG)
  execute_process(COMMAND ${XENO_CONFIG} --version OUTPUT_VARIABLE Xenomai_VERSION
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --posix --cflags OUTPUT_VARIABLE _xeno_cflags
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND ${XENO_CONFIG} --posix --ldflags OUTPUT_VARIABLE _xeno_ldflags
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  separate_arguments(_xeno_cflags UNIX_COMMAND "${_xeno_cflags}")
  separate_arguments(_xeno_ldflags UNIX_COMMAND "${_xeno_ldflags}")
endif()
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(Xenomai REQUIRED_VARS XENO_CONFIG VERSION_VAR Xenomai_VERSION)
if(Xenomai_FOUND AND NOT TARGET Xenomai::cobalt)
  add_library(Xenomai::cobalt INTERFACE IMPORTED)
  set_target_properties(Xenomai::cobalt PROPERTIES INTERFACE_COMPILE_OPTIONS "${_xeno_cflags}")
  add_library(Xenomai::posix_exe INTERFACE IMPORTED)
  set_target_properties(Xenomai::posix_exe PROPERTIES INTERFACE_LINK_OPTIONS "${_xeno_ldflags}")
endif()
