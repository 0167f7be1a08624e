#pragma once
// The state every Node of one document shares: where it came from, an index to locate marks in
// its text, and what went wrong. Private to the config module (node.hpp only declares it).

#include <cstddef>
#include <string>

#include "config/text_index.hpp"
#include "vigil/config/error.hpp"
#include "vigil/config/load.hpp"

namespace vigil::config::detail {

/// At most this many errors are kept per document (kMaxErrorsListed); past it they are only
/// counted, and the list ends with one saying how many more there were. Bounds memory, time
/// (each error is compared with the kept ones) and output for a file with an error in each of
/// 100,000 entries.
inline constexpr std::size_t kMaxErrorsKept = kMaxErrorsListed;

/// "N more errors not listed (only the first 100 are)", as the last error of a capped list.
[[nodiscard]] ConfigError more_errors(const std::string& file, std::size_t more);

/// Sorts `errors` by location (stable), drops repeated ones, and keeps the first
/// kMaxErrorsKept followed, when some were dropped for the cap, by more_errors(). O(n log n).
void tidy_errors(ConfigErrors& errors, std::size_t already_suppressed = 0);

struct Document {
  std::string file;
  std::string text;  // kept to turn yaml-cpp's byte columns into character columns
  TextIndex index;   // over `text`; set once `text` has its final address
  ConfigErrors errors;
  std::size_t suppressed = 0;  // errors past kMaxErrorsKept, counted only

  Document(std::string file_name, std::string source)
      : file(std::move(file_name)), text(std::move(source)), index(text) {}
  Document() : index(text) {}
  Document(const Document&) = delete;
  Document& operator=(const Document&) = delete;

  [[nodiscard]] std::pair<int, int> locate(const YAML::Mark& mark) const {
    return index.locate(mark);
  }

  void add(ConfigError error);
};

}  // namespace vigil::config::detail
