# Install + export: `find_package(vigil)` then link `vigil::vigil` (or one vigil::<module>).
include(CMakePackageConfigHelpers)

install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/vigil DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${PROJECT_BINARY_DIR}/include/vigil/version.hpp
              ${PROJECT_BINARY_DIR}/include/vigil/build_config.hpp
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/vigil)

install(TARGETS ${VIGIL_MODULE_TARGETS} vigil_vigil vigil_alloc_guard
  EXPORT vigil-targets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  OBJECTS DESTINATION ${CMAKE_INSTALL_LIBDIR}/vigil-objects
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

set(VIGIL_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/vigil)
install(EXPORT vigil-targets NAMESPACE vigil:: DESTINATION ${VIGIL_CMAKE_DIR})
export(EXPORT vigil-targets NAMESPACE vigil:: FILE ${PROJECT_BINARY_DIR}/vigil-targets.cmake)

# For vigil-config.cmake: the Xenomai prefix this build used, a fallback for consumers.
if(VIGIL_PLATFORM STREQUAL "cobalt")
  get_filename_component(VIGIL_XENOMAI_ROOT "${XENO_CONFIG}" DIRECTORY)
  get_filename_component(VIGIL_XENOMAI_ROOT "${VIGIL_XENOMAI_ROOT}" DIRECTORY)
  install(FILES ${PROJECT_SOURCE_DIR}/cmake/FindXenomai.cmake DESTINATION ${VIGIL_CMAKE_DIR})
  # Beside the build tree's vigil-config.cmake too, which finds it the same way.
  configure_file(${PROJECT_SOURCE_DIR}/cmake/FindXenomai.cmake
    ${PROJECT_BINARY_DIR}/FindXenomai.cmake COPYONLY)
else()
  set(VIGIL_XENOMAI_ROOT "")
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/vigil-config.cmake.in
  ${PROJECT_BINARY_DIR}/vigil-config.cmake INSTALL_DESTINATION ${VIGIL_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/vigil-config-version.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/vigil-config.cmake ${PROJECT_BINARY_DIR}/vigil-config-version.cmake
  DESTINATION ${VIGIL_CMAKE_DIR})
