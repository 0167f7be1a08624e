#pragma once
/// @file
/// `vigil::expected<T, E>`: the result type of vigil's fallible operations off the real-time path.
///
/// It is `tl::expected` where CMake found tl-expected, otherwise `std::expected` (C++23; GCC 12
/// ships it with -std=c++23). Both spell the same API (`has_value()`, `value()`, `error()`,
/// `operator*`, `value_or`); use `vigil::unexpected(e)` to return an error. GCC 12's
/// std::expected has no monadic operations (and_then, transform): vigil does not use them.

#include "vigil/build_config.hpp"

#if VIGIL_EXPECTED_TL
#include <tl/expected.hpp>
namespace vigil {
// Using-declarations, not alias templates: `vigil::unexpected(e)` deduces its argument also with
// compilers without CTAD for alias templates (clang before 19, used for the fuzz preset).
using tl::expected;
using tl::unexpected;
}  // namespace vigil
#else
#include <expected>
namespace vigil {
using std::expected;
using std::unexpected;
}  // namespace vigil
#endif
