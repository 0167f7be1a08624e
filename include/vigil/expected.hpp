#pragma once
/// @file
/// `vigil::expected<T, E>`: the result type of vigil's fallible operations off the real-time path.
///
/// It is `tl::expected` where CMake found tl-expected, otherwise `std::expected` (C++23; GCC 12
/// ships it with -std=c++23). Both spell the same API (`has_value()`, `value()`, `error()`,
/// `operator*`, `value_or`); use `vigil::unexpected(e)` to return an error. GCC 12's
/// std::expected has no monadic operations (and_then, transform): vigil does not use them.

#include "vigil/config.hpp"

#if VIGIL_EXPECTED_TL
#include <tl/expected.hpp>
namespace vigil {
template <class T, class E>
using expected = tl::expected<T, E>;
// A using-declaration, not an alias template: `unexpected(e)` then deduces E on every compiler
// (class template argument deduction for alias templates is C++20, missing in clang before 19,
// which clang-tidy uses).
using tl::unexpected;
}  // namespace vigil
#else
#include <expected>
namespace vigil {
template <class T, class E>
using expected = std::expected<T, E>;
// A using-declaration, not an alias template: see above.
using std::unexpected;
}  // namespace vigil
#endif
