#pragma once
/// @file
/// Real-time-safe logging from a component's cycle: `VIGIL_LOG_DEBUG`, `VIGIL_LOG_INFO`,
/// `VIGIL_LOG_WARN`, `VIGIL_LOG_ERROR`.
///
/// ```cpp
/// void on_update() {
///   if (q > limit_) VIGIL_LOG_WARN("joint {} limit reached: {:.2f} rad", joint_, q);
/// }
/// ```
///
/// Usable in `on_update()` of a `vigil::Task<Derived>`, in an `UpdateGuard` scope (or between
/// `pre_update()` and `post_update()`), and in anything they call, on the cycle's thread.
///
/// What a call costs on the real-time thread: one thread-local load, one relaxed atomic load
/// (the component's run-time level), the arguments copied into a fixed-size record written in
/// place, and one push into the component's port. No allocation, lock, system call, exception
/// or formatting: the format string is checked at compile time (fmt's checks) and stored once
/// per call site in a static `CallSite`; the supervisor thread formats the record later.
///
/// Arguments: bool, char, integers of every width, float, double, long double, enums (shown
/// through an ADL `to_string(e)` when there is one, else through a fmt::formatter if there is
/// one, else as their number), pointers (as addresses), and strings (`const char*`, char arrays,
/// `std::string_view`, `std::string`, `FixedString<N>`), copied up to kMaxStringBytes bytes and
/// shown with "..." when cut. Numbers take their size in the record's 88 bytes; a string takes one
/// byte plus what fits (strings share what the numbers leave). Any other type is a compile error.
///
/// Outside a supervised cycle (no component to attribute the line to) a call is dropped and
/// counted (log::unattributed()). When the port is full the record is dropped and counted, per
/// component (log::dropped(), and the port's drop counter like any message).
///
/// Levels: calls below `VIGIL_LOG_LEVEL` (level.hpp) are compiled out and their arguments are
/// not evaluated; the others are filtered by the component's run-time level (log::set_level),
/// before their arguments are evaluated.
///
/// Link `vigil::log` (which brings fmt): the call site's decoder is compiled where it is used.

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <utility>

#include "vigil/bus/fixed_string.hpp"
#include "vigil/log/level.hpp"
#include "vigil/log/record.hpp"
#include "vigil/log/source.hpp"

namespace vigil::log::detail {

// --- what an argument is ----------------------------------------------------------------------

template <class T>
struct is_fixed_string : std::false_type {};
template <std::size_t N>
struct is_fixed_string<FixedString<N>> : std::true_type {};

template <class T>
inline constexpr bool is_char_array =
    std::is_array_v<T>&& std::is_same_v<std::remove_cv_t<std::remove_extent_t<T>>, char>;
template <class T>
inline constexpr bool is_c_string = std::is_same_v<T, const char*> || std::is_same_v<T, char*>;

template <class T>
inline constexpr bool is_string_arg = is_fixed_string<T>::value || is_char_array<T> ||
                                      is_c_string<T> ||
                                      (!std::is_arithmetic_v<T> && !std::is_pointer_v<T> &&
                                       std::is_convertible_v<const T&, std::string_view>);

template <class T>
inline constexpr bool is_wide_char = std::is_same_v<T, wchar_t> || std::is_same_v<T, char8_t> ||
                                     std::is_same_v<T, char16_t> || std::is_same_v<T, char32_t>;

template <class T>
inline constexpr bool is_number_arg = std::is_arithmetic_v<T> && !is_wide_char<T>;

template <class T>
inline constexpr bool is_pointer_arg = (std::is_pointer_v<T> && !is_c_string<T> &&
                                        !std::is_function_v<std::remove_pointer_t<T>>) ||
                                       std::is_null_pointer_v<T>;

template <class T>
inline constexpr bool is_supported_arg =
    is_string_arg<T> || is_number_arg<T> || std::is_enum_v<T> || is_pointer_arg<T>;

/// An enum shown through an ADL `to_string(e)` returning something string-like.
template <class E>
concept EnumWithToString = std::is_enum_v<E> && requires(E e) {
  { to_string(e) } -> std::convertible_to<std::string_view>;
};

/// The canonical type of any string argument (one decoder for all string types).
struct Str {};

/// The type an argument is recorded as: numbers and enums as themselves, strings as Str,
/// pointers as const void*.
template <class T>
using canon_t = std::conditional_t<is_string_arg<T>, Str,
                                   std::conditional_t<is_pointer_arg<T>, const void*, T>>;

template <class T>
using bare_t = std::remove_cvref_t<T>;

/// What a canonical type is stored as in the payload (strings are special).
template <class C>
struct stored {
  using type = C;
};
template <class C>
requires std::is_enum_v<C>
struct stored<C> {
  using type = std::underlying_type_t<C>;
};
template <>
struct stored<const void*> {
  using type = std::uintptr_t;
};
template <class C>
using stored_t = typename stored<C>::type;

/// Bytes a canonical type always takes in the payload (a string: its length byte).
template <class C>
consteval std::size_t fixed_bytes() {
  if constexpr (std::is_same_v<C, Str>) {
    return 1;
  } else {
    return sizeof(stored_t<C>);
  }
}

/// What the supervisor formats for a canonical type (and what the format string is checked
/// against): strings as strings, enums through to_string / their formatter / their number.
template <class C>
struct shown {
  using type = C;
};
template <>
struct shown<Str> {
  using type = std::string;
};
template <class C>
requires std::is_enum_v<C>
struct shown<C> {
  using type = decltype([] {
    if constexpr (EnumWithToString<C>) {
      return std::remove_cvref_t<decltype(to_string(C{}))>{};
    } else if constexpr (fmt::is_formattable<C>::value) {
      return C{};
    } else {
      return std::underlying_type_t<C>{};
    }
  }());
};
template <class C>
using shown_t = typename shown<C>::type;

/// The type the format string is checked against (a string view for strings, so that the
/// check needs no allocation-capable type).
template <class C>
using checked_t = std::conditional_t<std::is_same_v<C, Str>, std::string_view, shown_t<C>>;

// --- the payload layout -----------------------------------------------------------------------

template <class... C>
struct Layout {
  static constexpr std::size_t count = sizeof...(C);
  static constexpr std::size_t fixed_total = (std::size_t{0} + ... + fixed_bytes<C>());
  /// reserve[i]: bytes the arguments after argument i always need.
  static constexpr std::array<std::size_t, count + 1> reserve = [] {
    std::array<std::size_t, count + 1> r{};
    constexpr std::array<std::size_t, count + 1> sizes{fixed_bytes<C>()..., 0};
    for (std::size_t i = count; i-- > 0;) r[i] = r[i + 1] + sizes[i + 1];
    return r;
  }();
};

// --- encoding (RT side) -----------------------------------------------------------------------

template <class T>
[[nodiscard]] inline std::string_view string_of(const T& v) noexcept {
  if constexpr (is_fixed_string<T>::value) {
    return v.view();
  } else if constexpr (is_char_array<T>) {
    return std::string_view(v, ::strnlen(v, std::extent_v<T>));
  } else if constexpr (is_c_string<T>) {
    if (v == nullptr) return std::string_view("(null)");
    // Bounded: one byte more than is copied tells whether the string was longer. (A loop, not
    // strnlen: GCC warns when the bound exceeds a literal's size, which strnlen allows.)
    std::size_t n = 0;
    while (n <= kMaxStringBytes && v[n] != '\0') ++n;
    return std::string_view(v, n);
  } else {
    return std::string_view(v);
  }
}

/// Writes one argument at `p` (advancing it); a string may use the bytes up to `limit`.
template <class T>
inline void put(std::byte*& p, const std::byte* limit, const T& v) noexcept {
  if constexpr (is_string_arg<T>) {
    const std::string_view s = string_of(v);
    std::size_t avail = static_cast<std::size_t>(limit - p) - 1;
    if (avail > kMaxStringBytes) avail = kMaxStringBytes;
    std::size_t n = s.size() <= avail ? s.size() : avail;
    const bool cut = n < s.size();
    // Never cut inside a UTF-8 sequence: back up to the start of the cut character.
    if (cut) {
      while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0U) == 0x80U) --n;
    }
    *p++ = static_cast<std::byte>(n | (cut ? kTruncatedBit : 0U));
    if (n > 0) std::memcpy(p, s.data(), n);
    p += n;
  } else if constexpr (is_pointer_arg<T>) {
    const auto u = reinterpret_cast<std::uintptr_t>(static_cast<const volatile void*>(v));
    std::memcpy(p, &u, sizeof(u));
    p += sizeof(u);
  } else if constexpr (std::is_enum_v<T>) {
    const auto u = static_cast<std::underlying_type_t<T>>(v);
    std::memcpy(p, &u, sizeof(u));
    p += sizeof(u);
  } else {
    std::memcpy(p, &v, sizeof(T));
    p += sizeof(T);
  }
}

template <class... T, std::size_t... I>
[[nodiscard]] inline std::size_t encode(std::byte* base, std::index_sequence<I...> /*unused*/,
                                        const T&... args) noexcept {
  using L = Layout<canon_t<T>...>;
  std::byte* p = base;
  (put(p, base + kPayloadBytes - L::reserve[I], args), ...);
  return static_cast<std::size_t>(p - base);
}

// --- decoding (supervisor side) ----------------------------------------------------------------

struct Reader {
  const std::byte* p;
  const std::byte* end;
  bool ok = true;
};

template <class C>
shown_t<C> get(Reader& r) {
  if constexpr (std::is_same_v<C, Str>) {
    if (r.end - r.p < 1) {
      r.ok = false;
      return {};
    }
    const auto h = static_cast<std::uint8_t>(*r.p++);
    const std::size_t n = h & static_cast<std::uint8_t>(~kTruncatedBit);
    if (static_cast<std::size_t>(r.end - r.p) < n) {
      r.ok = false;
      return {};
    }
    std::string s(reinterpret_cast<const char*>(r.p), n);
    r.p += n;
    if ((h & kTruncatedBit) != 0) s += "...";
    return s;
  } else {
    stored_t<C> v{};
    if (static_cast<std::size_t>(r.end - r.p) < sizeof(v)) {
      r.ok = false;
      return shown_t<C>{};
    }
    std::memcpy(&v, r.p, sizeof(v));
    r.p += sizeof(v);
    if constexpr (std::is_same_v<C, const void*>) {
      return reinterpret_cast<const void*>(v);
    } else if constexpr (EnumWithToString<C>) {
      return to_string(static_cast<C>(v));
    } else if constexpr (std::is_enum_v<C>) {
      if constexpr (std::is_same_v<shown_t<C>, C>) {
        return static_cast<C>(v);
      } else {
        return v;
      }
    } else {
      return v;
    }
  }
}

/// The decoder of one list of canonical argument types. Supervisor side.
template <class... C>
void decode(std::string& out, const CallSite& site, const LogRecord& record) {
  const std::size_t size = std::min<std::size_t>(record.size, kPayloadBytes);
  Reader r{record.payload.data(), record.payload.data() + size};
  // Braced initialisation: the arguments are read left to right.
  const std::tuple<shown_t<C>...> values{get<C>(r)...};
  if (!r.ok) {
    out += "<malformed log record>";
    return;
  }
  std::apply(
      [&](const auto&... v) {
        fmt::vformat_to(std::back_inserter(out), fmt::string_view(site.format),
                        fmt::make_format_args(v...));
      },
      values);
}

// --- call sites --------------------------------------------------------------------------------

/// What the macro's consteval lambda says about its call site.
struct SiteText {
  Level level;
  std::string_view format;
  std::string_view file;
  std::uint32_t line;
};

/// A format string as a string view (a literal or a constexpr std::string_view).
template <class S>
consteval std::string_view format_view(const S& s) {
  const fmt::string_view v(s);
  return {v.data(), v.size()};
}

/// fmt's compile-time check of the call site's format string against the argument types: a
/// mismatch is a compile error here (fmt reports it through its error handler: "argument not
/// found", "invalid type specifier", ...).
template <class Tag, class... C>
consteval bool check_format() {
  constexpr SiteText t = Tag{}();
  [[maybe_unused]] const fmt::format_string<checked_t<C>...> checked(t.format);
  return true;
}

template <class Tag, class... C>
consteval CallSite make_site() {
  static_assert(check_format<Tag, C...>());
  constexpr SiteText t = Tag{}();
  return CallSite{t.level, t.format, t.file, t.line, &decode<C...>};
}

/// One static CallSite per call site (Tag is the call site's own lambda type).
template <class Tag, class... C>
inline constexpr CallSite kSite = make_site<Tag, C...>();

template <class T>
consteval bool check_argument() {
  static_assert(is_supported_arg<T>,
                "VIGIL_LOG: this argument type cannot be logged from the real-time path; log "
                "numbers, bool, char, enums, pointers or strings (const char*, std::string_view, "
                "std::string, vigil::FixedString: copied up to 32 bytes), or format it yourself "
                "outside the cycle");
  return is_supported_arg<T>;
}

/// The body of a log call, after the level checks. RT-safe.
template <class Tag, class... A>
[[gnu::always_inline]] inline void emit(Tag /*site*/, Source& source, const A&... args) noexcept {
  if constexpr ((check_argument<bare_t<A>>() && ...)) {
    using L = Layout<canon_t<bare_t<A>>...>;
    static_assert(L::fixed_total <= kPayloadBytes,
                  "VIGIL_LOG: too many arguments for one record (88 bytes: numbers take their "
                  "size, strings one byte plus their text); split the line in two");
    LogRecord& r = *source.scratch();
    r.site = &kSite<Tag, canon_t<bare_t<A>>...>;
    r.cycle = source.cycle();
    r.time_ns = source.time_ns();
    r.size = static_cast<std::uint8_t>(
        encode<bare_t<A>...>(r.payload.data(), std::index_sequence_for<A...>{}, args...));
    (void)source.push();
  }
}

/// True when calls at `l` are compiled in under the threshold `Threshold` (VIGIL_LOG_LEVEL).
template <int Threshold>
[[nodiscard]] constexpr bool compiled_in(Level l) noexcept {
  return static_cast<int>(l) >= Threshold;
}

template <class... A>
struct TypeList {};
/// The argument types of a call, without evaluating the arguments (never defined).
template <class... A>
TypeList<bare_t<A>...> types_of(const A&... args);

/// A call compiled out by VIGIL_LOG_LEVEL: nothing runs, but its arguments and format string are
/// still checked, so that raising the level never hides a broken call.
template <class Tag, class List>
struct CompiledOut;
template <class Tag, class... A>
struct CompiledOut<Tag, TypeList<A...>> {
  static constexpr bool arguments_ok = (check_argument<A>() && ...);
  static_assert(!arguments_ok || check_format<Tag, canon_t<A>...>());
};

/// A call outside any supervised cycle: counted, dropped.
inline void note_unattributed() noexcept { g_unattributed.fetch_add(1, std::memory_order_relaxed); }

}  // namespace vigil::log::detail

/// The call site's description, as a consteval lambda whose type is unique to the call site.
#define VIGIL_LOG_SITE_(level, format)                                                        \
  []() consteval {                                                                            \
    return ::vigil::log::detail::SiteText{(level), ::vigil::log::detail::format_view(format), \
                                          __FILE__, __LINE__};                                \
  }

/// Logs at `level` (a vigil::log::Level): `VIGIL_LOG_AT(vigil::log::Level::Warn, "x = {}", x)`.
/// The format string must be a constant: a string literal (checked at compile time exactly as
/// fmt::format_string checks it, so FMT_STRING is neither needed nor accepted).
#define VIGIL_LOG_AT(level, format, ...)                                                       \
  do {                                                                                         \
    if constexpr (::vigil::log::detail::compiled_in<VIGIL_LOG_LEVEL>(level)) {                 \
      ::vigil::log::Source* const vigil_log_source_ = ::vigil::log::detail::t_current;         \
      if (vigil_log_source_ == nullptr) [[unlikely]] {                                         \
        ::vigil::log::detail::note_unattributed();                                             \
      } else if (vigil_log_source_->enabled(level)) {                                          \
        ::vigil::log::detail::emit(VIGIL_LOG_SITE_(level, format),                             \
                                   *vigil_log_source_ __VA_OPT__(, ) __VA_ARGS__);             \
      }                                                                                        \
    } else {                                                                                   \
      (void)sizeof(::vigil::log::detail::CompiledOut<decltype(VIGIL_LOG_SITE_(level, format)), \
                                                     decltype(::vigil::log::detail::types_of(  \
                                                         __VA_ARGS__))>);                      \
    }                                                                                          \
  } while (false)

/// Logs at Debug. See the file comment for what may be logged and what it costs.
#define VIGIL_LOG_DEBUG(format, ...) \
  VIGIL_LOG_AT(::vigil::log::Level::Debug, format __VA_OPT__(, ) __VA_ARGS__)
/// Logs at Info.
#define VIGIL_LOG_INFO(format, ...) \
  VIGIL_LOG_AT(::vigil::log::Level::Info, format __VA_OPT__(, ) __VA_ARGS__)
/// Logs at Warn.
#define VIGIL_LOG_WARN(format, ...) \
  VIGIL_LOG_AT(::vigil::log::Level::Warn, format __VA_OPT__(, ) __VA_ARGS__)
/// Logs at Error.
#define VIGIL_LOG_ERROR(format, ...) \
  VIGIL_LOG_AT(::vigil::log::Level::Error, format __VA_OPT__(, ) __VA_ARGS__)
