#pragma once
// Included first by every file of src/platform/cobalt/: refuses to compile them unless the build
// is consistent. Two independent sources must agree: the compiler flags of `xeno-config --cobalt
// --cflags` (which define __COBALT__), applied by src/platform/cobalt/CMakeLists.txt, and the
// project's configuration (VIGIL_PLATFORM=cobalt, written to vigil/build_config.hpp by CMake).
// This header includes no Xenomai header itself.

#include "vigil/build_config.hpp"

#if !defined(__COBALT__)
// Xenomai::cobalt (cmake/FindXenomai.cmake) carries those flags.
#error "src/platform/cobalt is compiled without `xeno-config --cobalt --cflags` (no __COBALT__)"
#endif
#if defined(__COBALT_WRAP__)
// vigil is built and linked without libcobalt's POSIX --wrap list (docs/design/platform.md, "One
// kind of thread, one kind of lock"); `--posix` flags mean a build that does not follow it.
#error "src/platform/cobalt is compiled with `xeno-config --posix` flags; vigil uses `--cobalt`"
#endif
#if !VIGIL_PLATFORM_COBALT || VIGIL_PLATFORM_LINUX
#error \
    "src/platform/cobalt is compiled but vigil/build_config.hpp says VIGIL_PLATFORM is not cobalt"
#endif
#if !defined(__cplusplus) || __cplusplus < 202002L
#error "vigil's platform layer needs C++20"
#endif
