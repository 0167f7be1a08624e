#pragma once
/// @file
/// `VIGIL_ASSERT(cond, msg)`: contract checks compiled out when NDEBUG is defined (FMT_ASSERT).

#ifdef NDEBUG
#define VIGIL_ASSERT(cond, msg) static_cast<void>(0)
#else
#include <cstdio>
#include <cstdlib>
#define VIGIL_ASSERT(cond, msg)                                                                   \
  ((cond) ? static_cast<void>(0)                                                                  \
          : (std::fprintf(stderr, "%s:%d: vigil assertion failed: %s (%s)\n", __FILE__, __LINE__, \
                          #cond, msg),                                                            \
             std::abort()))
#endif
