#pragma once
/// @file
/// Loading a YAML document from a file or a string, optionally straight through a schema loader.
///
/// Loading fails, with every problem found, when the file cannot be read ("cannot read file:
/// No such file or directory"), on a YAML syntax error (at yaml-cpp's line and column), when a
/// mapping holds the same key twice (yaml-cpp would silently keep one; each duplicate is reported
/// at its own location with the first one's position), and when a file holds more than one
/// document. An empty file loads as a null root, which reads as an empty mapping.
///
/// Whatever the input, loading ends and its memory is bounded: a file is refused, with an error
/// at the offending place, when it is larger than kMaxFileBytes, nests mappings and sequences
/// deeper than kMaxNestingDepth, holds more than kMaxNodes values, holds an alias that refers to
/// a node containing it, or aliases that expand to more than kMaxAliasExpansion values. Past
/// kMaxErrorsListed errors, the list ends with one saying how many more there were.
/// (docs/reference/configuration-limits.md.)
///
/// Nothing here is RT-safe (file I/O, allocation). Each call is independent and thread-safe.

#include <cstddef>
#include <exception>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "vigil/config/error.hpp"
#include "vigil/config/node.hpp"
#include "vigil/expected.hpp"

namespace vigil::config {

/// Largest configuration file accepted, in bytes (4 MiB). A larger file is refused ("file is
/// larger than 4 MiB") before it is parsed; load_file reads no more than this plus one byte.
inline constexpr std::size_t kMaxFileBytes = std::size_t{4} << 20;
/// Deepest nesting of mappings and sequences accepted (100 levels).
inline constexpr int kMaxNestingDepth = 100;
/// Most values (scalars, mappings, sequences, aliases, empty values) in one file (500,000).
inline constexpr std::size_t kMaxNodes = 500'000;
/// Most values that aliases may add to a document when expanded, all aliases together (100,000):
/// `*a` standing for a mapping of 10 values adds 10. Bounds what any reader of the document may
/// have to walk.
inline constexpr std::size_t kMaxAliasExpansion = 100'000;
/// Most errors listed for one file (100); a last error says how many more were found.
inline constexpr std::size_t kMaxErrorsListed = 100;

/// Reads and parses the YAML file at `path`; errors name the file as `path.string()`.
/// Fails as described in the file comment.
[[nodiscard]] expected<Node, ConfigErrors> load_file(const std::filesystem::path& path);

/// Parses `text` as a YAML document; errors name the file `name`.
/// Fails as described in the file comment.
[[nodiscard]] expected<Node, ConfigErrors> load_string(std::string_view text,
                                                       std::string name = "<string>");

namespace detail {
template <class R>
struct LoaderResult {
  using Value = R;
  static constexpr bool kExpected = false;
};
template <class T>
struct LoaderResult<expected<T, ConfigErrors>> {
  using Value = T;
  static constexpr bool kExpected = true;
};
template <class F>
using LoaderReturn = std::remove_cvref_t<std::invoke_result_t<F&, const Node&>>;
template <class F>
using Loaded = typename LoaderResult<LoaderReturn<F>>::Value;

// The error recorded when a loader throws: "loader failed: <what()>", at the document's file.
[[nodiscard]] ConfigError loader_exception_error(const Node& root, std::exception_ptr e);
// The document's errors followed by the loader's own, in file order, each once. When `failed`
// and there is none, adds one saying that the loader gave no reason.
[[nodiscard]] ConfigErrors merge_errors(const Node& root, ConfigErrors loader_errors, bool failed);
}  // namespace detail

/// A schema loader: called with the root of a document, it returns either `T` or
/// `expected<T, ConfigErrors>`. Errors it records through `Node` count as failures even when it
/// returns a value, so a loader cannot accidentally succeed with defaults.
template <class F>
concept Loader = std::invocable<F&, const Node&> && !std::is_void_v<detail::LoaderReturn<F>>;

namespace detail {
/// Runs `loader` on `root`; the result is its value only if neither it nor the document has an
/// error. An exception from the loader becomes an error (a loader never crashes the caller).
template <Loader F>
expected<Loaded<F>, ConfigErrors> run_loader(const Node& root, F& loader) {
  using Result = LoaderReturn<F>;
  std::optional<Loaded<F>> value;
  ConfigErrors own;
  try {
    if constexpr (LoaderResult<Result>::kExpected) {
      Result r = std::invoke(loader, root);
      if (r.has_value()) {
        value.emplace(std::move(*r));
      } else {
        own = std::move(r.error());
      }
    } else {
      value.emplace(std::invoke(loader, root));
    }
  } catch (...) {
    own.push_back(loader_exception_error(root, std::current_exception()));
  }
  ConfigErrors all = merge_errors(root, std::move(own), !value.has_value());
  if (!all.empty() || !value.has_value()) return vigil::unexpected<ConfigErrors>(std::move(all));
  return std::move(*value);
}
}  // namespace detail

/// Loads the file at `path` and runs `loader` on its root: the loader's value, or every error of
/// the file and of the loader. Not RT-safe.
template <Loader F>
[[nodiscard]] expected<detail::Loaded<F>, ConfigErrors> load_file(const std::filesystem::path& path,
                                                                  F&& loader) {
  expected<Node, ConfigErrors> root = load_file(path);
  if (!root.has_value()) return vigil::unexpected<ConfigErrors>(std::move(root.error()));
  return detail::run_loader(*root, loader);
}

/// Parses `text` (named `name` in errors) and runs `loader` on its root. Not RT-safe.
template <Loader F>
[[nodiscard]] expected<detail::Loaded<F>, ConfigErrors> load_string(std::string_view text,
                                                                    std::string name, F&& loader) {
  expected<Node, ConfigErrors> root = load_string(text, std::move(name));
  if (!root.has_value()) return vigil::unexpected<ConfigErrors>(std::move(root.error()));
  return detail::run_loader(*root, loader);
}

}  // namespace vigil::config
