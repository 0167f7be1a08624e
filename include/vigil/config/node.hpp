#pragma once
/// @file
/// `Node`: a value of a loaded YAML document that knows where it came from, so that schema code
/// reads naturally and every error names its file, line, column and field.
///
/// A schema loader reads the values it needs and never checks for errors itself: each accessor
/// that finds a problem records a `ConfigError` in the document (located at the offending value,
/// or at the enclosing mapping for a missing key) and returns a placeholder (`T{}`, or the
/// fallback), so that the loader goes on and every error of the document is reported at once.
/// The loader ends with `return root.finish(std::move(value));`, which returns the value or all
/// errors.
///
/// ```
/// expected<Limits, ConfigErrors> load_limits(const config::Node& n) {
///   n.reject_unknown_keys({"period", "warn_fraction", "policy"});
///   Limits l;
///   l.period_ns = n.required_period("period");                   // "1ms" or "1 kHz"
///   l.warn_fraction = n.optional("warn_fraction", 0.8, config::in_range(0.0, 1.0));
///   l.policy = n.required_enum<Policy>("policy", {{"FIFO", Policy::Fifo}, {"OTHER",
///   Policy::Other}}); return n.finish(std::move(l));
/// }
/// ```
///
/// Thread safety: a document (every `Node` obtained from one `load_*` call, and their copies)
/// shares one error list and must be used by one thread at a time; different documents are
/// independent. Nothing here is RT-safe: every call may allocate.

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <concepts>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>
#include <ranges>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "vigil/config/error.hpp"
#include "vigil/config/units.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::config {

class Node;

namespace detail {
struct Document;

/// What load.cpp needs from a Node's internals (the Document is private to src/config).
struct NodeAccess {
  /// A new document named `file` with source `text`, indexed to locate marks in O(log lines).
  [[nodiscard]] static std::shared_ptr<Document> make_document(std::string file, std::string text);
  /// 1-based line and column of `mark` in `doc`'s text; the column counts characters (UTF-8 code
  /// points), not bytes as yaml-cpp does. {0, 0} for a null mark.
  [[nodiscard]] static std::pair<int, int> locate(const Document& doc, const YAML::Mark& mark);
  /// The root of `doc`, whose parsed tree is `root`.
  [[nodiscard]] static Node make_root(std::shared_ptr<Document> doc, const YAML::Node& root);
  /// The document `node` belongs to.
  [[nodiscard]] static const Document& document(const Node& node);
  /// `locate(node's document, mark)`.
  [[nodiscard]] static std::pair<int, int> text_location(const Node& node, const YAML::Mark& mark);
};

template <class>
inline constexpr bool kAlwaysFalse = false;

template <class T>
struct IsVector : std::false_type {};
template <class T, class A>
struct IsVector<std::vector<T, A>> : std::true_type {};

/// Shortest text that reads back to `v` ("0.5", "1e-09", "42").
template <class V>
std::string number_text(const V& v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// `a < b` without sign-compare surprises between integer types.
template <class A, class B>
constexpr bool less(const A& a, const B& b) {
  if constexpr (std::is_integral_v<A> && std::is_integral_v<B>) {
    return std::cmp_less(a, b);
  } else {
    return a < b;
  }
}
}  // namespace detail

/// A check that a schema applies to a converted value: it returns nullopt when `value` is
/// acceptable, otherwise the requirement it violates, worded to be followed by ", got '<text>'"
/// ("must be between 0 and 1"). Any callable with that signature works, e.g. a lambda.
template <class C, class T>
concept Check = std::is_invocable_r_v < std::optional<std::string>,
const C&, const T& > ;

/// Check: `min <= value <= max` ("must be between 0 and 1"). For durations prefer
/// `duration_in_range`, whose message shows units.
template <class T>
struct InRange {
  T min;  ///< Smallest accepted value.
  T max;  ///< Largest accepted value.
  /// nullopt when `min <= value <= max`, else the requirement. Not RT-safe (allocates).
  template <class V>
  requires std::totally_ordered_with<V, T> std::optional<std::string>
  operator()(const V& value) const {
    if (detail::less(value, min) || detail::less(max, value)) {
      return "must be between " + detail::number_text(min) + " and " + detail::number_text(max);
    }
    return std::nullopt;
  }
};

/// Check: `min <= value <= max` for any arithmetic value. Not RT-safe (allocates on failure).
template <class T>
[[nodiscard]] constexpr InRange<T> in_range(T min, T max) {
  return InRange<T>{min, max};
}

/// Check: value > 0 ("must be positive").
struct Positive {
  /// nullopt when `value > 0`, else the requirement.
  template <class V>
  requires std::is_arithmetic_v<V> std::optional<std::string>
  operator()(const V& value) const {
    if (value > V{}) return std::nullopt;
    return "must be positive";
  }
};

/// Check: value > 0, for any arithmetic value (durations included).
[[nodiscard]] constexpr Positive positive() { return {}; }

/// Check: value >= 0 ("must be zero or more").
struct NonNegative {
  /// nullopt when `value >= 0`, else the requirement.
  template <class V>
  requires std::is_arithmetic_v<V> std::optional<std::string>
  operator()(const V& value) const {
    if (!(value < V{})) return std::nullopt;
    return "must be zero or more";
  }
};

/// Check: value >= 0, for any arithmetic value.
[[nodiscard]] constexpr NonNegative non_negative() { return {}; }

/// Check: a string or sequence is not empty ("must not be empty").
struct NonEmpty {
  /// nullopt when `value` is not empty, else the requirement.
  template <class V>
  requires requires(const V& v) { v.empty(); }
  std::optional<std::string> operator()(const V& value) const {
    if (!value.empty()) return std::nullopt;
    return "must not be empty";
  }
};

/// Check: a string or sequence is not empty.
[[nodiscard]] constexpr NonEmpty non_empty() { return {}; }

/// Check: a duration in nanoseconds within `[min, max]` ("must be between 1ms and 1s").
struct DurationInRange {
  Nanos min;  ///< Shortest accepted duration, in nanoseconds.
  Nanos max;  ///< Longest accepted duration, in nanoseconds.
  /// nullopt when `min <= value <= max`, else the requirement with units.
  std::optional<std::string> operator()(Nanos value) const {
    if (value >= min && value <= max) return std::nullopt;
    return "must be between " + format_duration(min) + " and " + format_duration(max);
  }
};

/// Check: a duration within `[min, max]`, reported with units.
[[nodiscard]] constexpr DurationInRange duration_in_range(Nanos min, Nanos max) {
  return DurationInRange{min, max};
}

/// The spelling of one enumerator in a configuration file: `{"FIFO", SchedPolicy::Fifo}`.
template <class E>
struct EnumName {
  std::string_view name;  ///< The spelling accepted in the file (case-sensitive).
  E value;                ///< The enumerator it stands for.
};

namespace detail {
template <class T>
struct EnumNameTraits {
  static constexpr bool kIsEnumName = false;
};
template <class E>
struct EnumNameTraits<EnumName<E>> {
  static constexpr bool kIsEnumName = true;
  using Enum = E;
};
}  // namespace detail

/// A range of `EnumName<E>` (typically a `constexpr std::array`), usable with `get_enum`,
/// `required_enum` and `optional_enum`.
template <class R>
concept EnumNames = std::ranges::forward_range<const R> &&
    detail::EnumNameTraits<std::remove_cv_t<std::ranges::range_value_t<const R>>>::kIsEnumName;

/// The enumeration named by an `EnumNames` range.
template <EnumNames R>
using EnumOf =
    typename detail::EnumNameTraits<std::remove_cv_t<std::ranges::range_value_t<const R>>>::Enum;

/// A value in a loaded YAML document, with its file, location and dotted path.
///
/// A `Node` is in one of three states. *Present*: the document has a value here. *Missing*: the
/// key does not exist (reading it as required reports "required key is missing" at the enclosing
/// mapping). *Unreachable*: an error was already reported on the way here (say `monitor` is a
/// number, so `monitor.period` cannot exist); accessors then return placeholders without
/// reporting again. Errors are recorded in the document and read back with `errors()` or
/// `finish()`; each distinct error is recorded once.
///
/// Empty values (`key:` or `key: ~`) are present but null: reading one as a number, a string or a
/// duration is an error ("got an empty value"), never a silent default; as a mapping or a
/// sequence it reads as empty.
///
/// Copies are cheap handles on the same document. Thread safety: see the file comment. Not
/// RT-safe.
class Node {
 public:
  /// An empty, present, null node of an unnamed document (so that containers can hold nodes).
  Node();

  // --- navigation -----------------------------------------------------------------------------

  /// The value at `key`, present or missing, for optional sections. On a scalar or a sequence,
  /// reports "expected a mapping" once and returns an unreachable node. On a null or missing
  /// node, returns a missing node.
  [[nodiscard]] Node operator[](std::string_view key) const;

  /// The value at `key`, which must exist: as `operator[]`, but a missing key is reported
  /// ("required key is missing") and the result is unreachable, so the keys read below it are
  /// not reported again.
  [[nodiscard]] Node at(std::string_view key) const;

  /// The key/value pairs of a mapping, in file order, for maps with user-chosen keys
  /// (`components: {motor: ..., arm: ...}`); each value's path is `<path>.<key>`. Empty for a
  /// null, missing or unreachable node; a scalar or a sequence is reported ("expected a
  /// mapping"). Keys that are not scalars are reported and skipped.
  [[nodiscard]] std::vector<std::pair<std::string, Node>> entries() const;

  /// The items of a sequence, in file order; each item's path is `<path>[<index>]`. Empty for a
  /// null, missing or unreachable node; a scalar or a mapping is reported ("expected a
  /// sequence").
  [[nodiscard]] std::vector<Node> elements() const;

  // --- inspection -----------------------------------------------------------------------------

  /// True when the document has a value here (even an empty one).
  [[nodiscard]] bool defined() const noexcept;
  /// True when this is a mapping that has `key`.
  [[nodiscard]] bool has(std::string_view key) const;
  /// True for a present empty value (`key:`, `key: ~`, `key: null`).
  [[nodiscard]] bool is_null() const;
  /// True for a present scalar (number, string, bool...).
  [[nodiscard]] bool is_scalar() const;
  /// True for a present mapping.
  [[nodiscard]] bool is_mapping() const;
  /// True for a present sequence.
  [[nodiscard]] bool is_sequence() const;
  /// Dotted path from the document root (`monitor.components.motor`, `filters[2].id`); empty for
  /// the root.
  [[nodiscard]] const std::string& path() const noexcept;
  /// The file name given to `load_file`/`load_string`.
  [[nodiscard]] const std::string& file() const noexcept;
  /// 1-based line that errors about this node point to (the enclosing mapping's for a missing
  /// node); 0 when unknown.
  [[nodiscard]] int line() const noexcept { return line_; }
  /// 1-based column (in characters), as `line()`.
  [[nodiscard]] int column() const noexcept { return column_; }
  /// The underlying yaml-cpp node, for what this class does not cover. Reading it directly
  /// bypasses error collection: yaml-cpp throws on misuse.
  [[nodiscard]] const YAML::Node& yaml() const noexcept { return yaml_; }

  // --- values ---------------------------------------------------------------------------------

  /// This value converted to `T`, then passed through `checks` in order (stopping at the first
  /// failure).
  ///
  /// `T` is `bool` (`true`/`false` only: `yes`/`on` are errors), an integer type (decimal or
  /// `0x` hex; out of `T`'s range is an error), a floating-point type (finite only), `std::string`
  /// (any scalar), or `std::vector` of these. On failure, records an error located at the value
  /// ("expected a number, got 'abc'", "must be between 0 and 1, got '1.5'") and returns `T{}` (a
  /// missing node reports "required key is missing"). For durations use `get_duration`, for
  /// enumerations `get_enum`.
  template <class T, Check<T>... C>
  [[nodiscard]] T get(const C&... checks) const {
    static_assert(std::is_default_constructible_v<T>,
                  "Node::get<T>: T must be default constructible");
    T value{};
    if (!present_or_report_()) return value;
    if (!convert_(value)) return T{};
    static_cast<void>((check_(value, checks) && ...));  // stops at the first failing check
    return value;
  }

  /// The value at `key`, which must exist: `(*this)[key].get<T>(checks...)`. Errors as `get`.
  template <class T, Check<T>... C>
  [[nodiscard]] T required(std::string_view key, const C&... checks) const {
    return (*this)[key].template get<T>(checks...);
  }

  /// The value at `key` if the key exists, else `fallback` (not checked). A key that exists
  /// with a bad or empty value is an error, never replaced by the fallback. Write
  /// `optional<std::string>(...)` for strings (a string literal would deduce `const char*`).
  template <class T, Check<T>... C>
  [[nodiscard]] T optional(std::string_view key, T fallback, const C&... checks) const {
    const Node child = (*this)[key];
    if (!child.defined()) return fallback;
    return child.template get<T>(checks...);
  }

  /// This value as a duration in nanoseconds, written with a unit ("2.5ms"; units.hpp gives the
  /// syntax). A bare number is an error. Errors as `get`; the message quotes the text.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos get_duration(const C&... checks) const {
    return time_(false, TimeUnit::None, checks...);
  }
  /// As `get_duration`, reading a bare number in `bare_unit` (`timeout_ms: 5`).
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos get_duration(TimeUnit bare_unit, const C&... checks) const {
    return time_(false, bare_unit, checks...);
  }
  /// The duration at `key`, which must exist.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos required_duration(std::string_view key, const C&... checks) const {
    return (*this)[key].time_(false, TimeUnit::None, checks...);
  }
  /// The duration at `key`, which must exist; bare numbers are in `bare_unit`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos required_duration(std::string_view key, TimeUnit bare_unit,
                                        const C&... checks) const {
    return (*this)[key].time_(false, bare_unit, checks...);
  }
  /// The duration at `key` if the key exists, else `fallback`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos optional_duration(std::string_view key, Nanos fallback,
                                        const C&... checks) const {
    return optional_time_(key, fallback, false, TimeUnit::None, checks...);
  }
  /// The duration at `key` if the key exists, else `fallback`; bare numbers are in `bare_unit`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos optional_duration(std::string_view key, Nanos fallback, TimeUnit bare_unit,
                                        const C&... checks) const {
    return optional_time_(key, fallback, false, bare_unit, checks...);
  }

  /// This value as a period in nanoseconds, written as a duration ("1ms") or a rate ("1 kHz",
  /// period rounded to the nearest nanosecond). Errors as `get_duration`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos get_period(const C&... checks) const {
    return time_(true, TimeUnit::None, checks...);
  }
  /// As `get_period`, reading a bare number as a duration in `bare_unit`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos get_period(TimeUnit bare_unit, const C&... checks) const {
    return time_(true, bare_unit, checks...);
  }
  /// The period at `key`, which must exist.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos required_period(std::string_view key, const C&... checks) const {
    return (*this)[key].time_(true, TimeUnit::None, checks...);
  }
  /// The period at `key`, which must exist; bare numbers are durations in `bare_unit`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos required_period(std::string_view key, TimeUnit bare_unit,
                                      const C&... checks) const {
    return (*this)[key].time_(true, bare_unit, checks...);
  }
  /// The period at `key` if the key exists, else `fallback`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos optional_period(std::string_view key, Nanos fallback,
                                      const C&... checks) const {
    return optional_time_(key, fallback, true, TimeUnit::None, checks...);
  }
  /// The period at `key` if the key exists, else `fallback`; bare numbers are in `bare_unit`.
  template <Check<Nanos>... C>
  [[nodiscard]] Nanos optional_period(std::string_view key, Nanos fallback, TimeUnit bare_unit,
                                      const C&... checks) const {
    return optional_time_(key, fallback, true, bare_unit, checks...);
  }

  /// This value as one of `names` (exact, case-sensitive match). Otherwise records
  /// "'FIFOO' is not one of FIFO, OTHER; did you mean 'FIFO'?" and returns `E{}`.
  /// Spell `E` out with a braced list: `get_enum<Policy>({{"FIFO", Policy::Fifo}, ...})`.
  template <class E>
  [[nodiscard]] E get_enum(std::initializer_list<EnumName<E>> names) const {
    return enum_(names);
  }
  /// As above, with the names in a range such as a `constexpr std::array<EnumName<E>, N>`.
  template <EnumNames R>
  [[nodiscard]] EnumOf<R> get_enum(const R& names) const {
    return enum_(names);
  }
  /// The enumerator at `key`, which must exist.
  template <class E>
  [[nodiscard]] E required_enum(std::string_view key,
                                std::initializer_list<EnumName<E>> names) const {
    return (*this)[key].enum_(names);
  }
  /// The enumerator at `key`, which must exist.
  template <EnumNames R>
  [[nodiscard]] EnumOf<R> required_enum(std::string_view key, const R& names) const {
    return (*this)[key].enum_(names);
  }
  /// The enumerator at `key` if the key exists, else `fallback`.
  template <class E>
  [[nodiscard]] E optional_enum(std::string_view key, E fallback,
                                std::initializer_list<EnumName<E>> names) const {
    const Node child = (*this)[key];
    return child.defined() ? child.enum_(names) : fallback;
  }
  /// The enumerator at `key` if the key exists, else `fallback`.
  template <EnumNames R>
  [[nodiscard]] EnumOf<R> optional_enum(std::string_view key, EnumOf<R> fallback,
                                        const R& names) const {
    const Node child = (*this)[key];
    return child.defined() ? child.enum_(names) : fallback;
  }

  // --- validation and errors ------------------------------------------------------------------

  /// Reports every key of this mapping that is not in `allowed`, each at its own location, with
  /// a hint: "unknown key; did you mean 'warn_fraction'?" or "unknown key; expected one of: a,
  /// b". Does nothing on a null, missing or unreachable node; reports a scalar or a sequence.
  void reject_unknown_keys(std::initializer_list<std::string_view> allowed) const {
    reject_unknown_keys_(std::span<const std::string_view>(allowed.begin(), allowed.size()));
  }
  /// As above, with the allowed keys in any range of strings (a `constexpr std::array`, or a
  /// `std::vector<std::string>` of names known only at run time).
  template <std::ranges::input_range R>
  requires std::convertible_to<std::ranges::range_reference_t<const R>, std::string_view>
  void reject_unknown_keys(const R& allowed) const {
    std::vector<std::string_view> keys;
    for (auto&& k : allowed) keys.emplace_back(k);
    reject_unknown_keys_(keys);
  }

  /// Records an error at this node, for checks the accessors cannot express
  /// (`n["warn"].error("must be below error (0.9)")`). The field is `path()`.
  void error(std::string message) const;

  /// True when any error has been recorded in this node's document.
  [[nodiscard]] bool has_errors() const noexcept;
  /// Every error recorded in this node's document so far, in file order: at most
  /// kMaxErrorsListed (load.hpp), then one saying how many more were found.
  [[nodiscard]] ConfigErrors errors() const;

  /// `value` when the document has no error, otherwise every error of the document. The usual
  /// last line of a loader: `return root.finish(std::move(cfg));`.
  template <class T>
  [[nodiscard]] expected<T, ConfigErrors> finish(T value) const {
    if (has_errors()) return vigil::unexpected<ConfigErrors>(errors());
    return value;
  }

 private:
  friend struct detail::NodeAccess;
  enum class State : std::uint8_t { Present, Missing, Unreachable };

  Node(std::shared_ptr<detail::Document> doc, const YAML::Node& yaml, std::string path, int line,
       int column, State state);

  // Present: true. Missing: reports "required key is missing", false. Unreachable: false.
  [[nodiscard]] bool present_or_report_() const;
  // Records `message` at this node.
  void fail_(std::string message) const;
  // Records "<requirement>, got <description of this value>" at this node.
  void fail_value_(std::string_view requirement) const;

  [[nodiscard]] bool convert_bool_(bool& out) const;
  [[nodiscard]] bool convert_signed_(std::int64_t& out, std::int64_t min, std::int64_t max) const;
  [[nodiscard]] bool convert_unsigned_(std::uint64_t& out, std::uint64_t max) const;
  [[nodiscard]] bool convert_floating_(double& out, bool to_float) const;
  [[nodiscard]] bool convert_string_(std::string& out) const;
  [[nodiscard]] bool convert_time_(Nanos& out, bool period, TimeUnit bare_unit) const;
  [[nodiscard]] std::optional<std::size_t> match_name_(
      std::span<const std::string_view> names) const;
  void reject_unknown_keys_(std::span<const std::string_view> allowed) const;

  template <class T>
  [[nodiscard]] bool convert_(T& out) const {
    if constexpr (std::is_same_v<T, bool>) {
      return convert_bool_(out);
    } else if constexpr (std::is_integral_v<T> && std::is_signed_v<T>) {
      std::int64_t v = 0;
      if (!convert_signed_(v, std::numeric_limits<T>::min(), std::numeric_limits<T>::max())) {
        return false;
      }
      out = static_cast<T>(v);
      return true;
    } else if constexpr (std::is_integral_v<T>) {
      std::uint64_t v = 0;
      if (!convert_unsigned_(v, std::numeric_limits<T>::max())) return false;
      out = static_cast<T>(v);
      return true;
    } else if constexpr (std::is_floating_point_v<T>) {
      double v = 0;
      if (!convert_floating_(v, std::is_same_v<T, float>)) return false;
      out = static_cast<T>(v);
      return true;
    } else if constexpr (std::is_same_v<T, std::string>) {
      return convert_string_(out);
    } else if constexpr (detail::IsVector<T>::value) {
      if (!is_sequence() && !is_null()) {
        fail_value_("expected a sequence");
        return false;
      }
      bool ok = true;
      for (const Node& item : elements()) {
        typename T::value_type v{};
        ok = item.present_or_report_() && item.convert_(v) && ok;
        out.push_back(std::move(v));
      }
      return ok;
    } else {
      static_assert(detail::kAlwaysFalse<T>,
                    "Node::get<T>: T must be bool, an integer, a floating-point type, std::string "
                    "or a std::vector of those; use get_duration/get_period for durations and "
                    "get_enum for enumerations");
      return false;
    }
  }

  template <class T, class C>
  bool check_(const T& value, const C& check) const {
    std::optional<std::string> problem = std::invoke(check, value);
    if (!problem) return true;
    fail_value_(*problem);
    return false;
  }

  template <class... C>
  Nanos time_(bool period, TimeUnit bare_unit, const C&... checks) const {
    if (!present_or_report_()) return 0;
    Nanos v = 0;
    if (!convert_time_(v, period, bare_unit)) return 0;
    static_cast<void>((check_(v, checks) && ...));
    return v;
  }

  template <class... C>
  Nanos optional_time_(std::string_view key, Nanos fallback, bool period, TimeUnit bare_unit,
                       const C&... checks) const {
    const Node child = (*this)[key];
    if (!child.defined()) return fallback;
    return child.time_(period, bare_unit, checks...);
  }

  template <class R>
  auto enum_(const R& names) const {
    using E = typename detail::EnumNameTraits<
        std::remove_cv_t<std::ranges::range_value_t<const R>>>::Enum;
    if (!present_or_report_()) return E{};
    std::vector<std::string_view> spelled;
    spelled.reserve(static_cast<std::size_t>(std::ranges::distance(names)));
    for (const auto& n : names) spelled.push_back(n.name);
    const std::optional<std::size_t> index = match_name_(spelled);
    if (!index) return E{};
    return std::ranges::next(std::ranges::begin(names),
                             static_cast<std::ranges::range_difference_t<const R>>(*index))
        ->value;
  }

  std::shared_ptr<detail::Document> doc_;
  YAML::Node yaml_;
  std::string path_;
  int line_ = 0;
  int column_ = 0;
  State state_ = State::Present;
};

}  // namespace vigil::config
