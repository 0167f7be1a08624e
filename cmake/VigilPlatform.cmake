# Platform selection (Orocos' OROCOS_TARGET check): an unknown value is a configuration error.
set(VIGIL_PLATFORM "linux" CACHE STRING "Target platform: linux (POSIX, PREEMPT_RT) or cobalt (Xenomai 3)")
set(VIGIL_PLATFORMS linux cobalt)
set_property(CACHE VIGIL_PLATFORM PROPERTY STRINGS ${VIGIL_PLATFORMS})
if(NOT VIGIL_PLATFORM IN_LIST VIGIL_PLATFORMS)
  message(FATAL_ERROR "VIGIL_PLATFORM='${VIGIL_PLATFORM}' is not one of: ${VIGIL_PLATFORMS}")
endif()

if(VIGIL_PLATFORM STREQUAL "cobalt")
  list(APPEND CMAKE_MODULE_PATH ${CMAKE_CURRENT_LIST_DIR})
  find_package(Xenomai REQUIRED)
  # The link flags name libcobalt with -L/-l, which CMake does not turn into an RPATH: give every
  # binary of the build tree the library folder, so tests and tools find libcobalt.so where it
  # was built against (on a Cobalt machine where it is elsewhere: LD_LIBRARY_PATH or ld.so.conf).
  list(APPEND CMAKE_BUILD_RPATH ${Xenomai_LIBRARY_DIRS})
endif()
