# Platform selection (Orocos' OROCOS_TARGET check): an unknown value is a configuration error.
set(VIGIL_PLATFORM "linux" CACHE STRING "Target platform: linux (POSIX, PREEMPT_RT) or cobalt (Xenomai 3)")
set(VIGIL_PLATFORMS linux cobalt)
set_property(CACHE VIGIL_PLATFORM PROPERTY STRINGS ${VIGIL_PLATFORMS})
if(NOT VIGIL_PLATFORM IN_LIST VIGIL_PLATFORMS)
  message(FATAL_ERROR "VIGIL_PLATFORM='${VIGIL_PLATFORM}' is not one of: ${VIGIL_PLATFORMS}")
endif()

if(VIGIL_PLATFORM STREQUAL "cobalt")
  list(APPEND CMAKE_MODULE_PATH ${CMAKE_CURRENT_LIST_DIR})
  # Xenomai::cobalt_link gives every binary that links vigil::platform (built or installed, vigil's
  # or a user's) a RUNPATH entry for Xenomai's library folder: libcobalt.so and libmodechk.so are
  # found where vigil was built against (elsewhere on the target: ld.so.conf or LD_LIBRARY_PATH).
  find_package(Xenomai REQUIRED)
endif()
