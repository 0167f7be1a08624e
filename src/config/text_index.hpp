#pragma once
// TextIndex: turns yaml-cpp's marks (byte position, 0-based line and byte column) into 1-based
// line and character column in O(log lines) per mark, whatever the length of a line.
//
// Built once per document in O(size). Locating each node by rescanning its line was quadratic
// for a one-line flow mapping of many entries (100,000 entries took tens of seconds).

#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <utility>
#include <vector>

namespace vigil::config::detail {

class TextIndex {
 public:
  TextIndex() = default;
  /// Indexes `text`, which must outlive the index (the Document owns both).
  explicit TextIndex(std::string_view text);

  /// 1-based line and column of `mark`; the column counts characters (UTF-8 code points), not
  /// bytes as yaml-cpp does, when yaml-cpp's byte column agrees with the text (it may not after a
  /// byte-order mark or for UTF-16 input, which yaml-cpp converts); otherwise yaml-cpp's column.
  /// {0, 0} for a null mark.
  [[nodiscard]] std::pair<int, int> locate(const YAML::Mark& mark) const;

 private:
  static constexpr std::size_t kBlock = 64;
  // UTF-8 continuation bytes in text_[0, pos).
  [[nodiscard]] std::size_t continuations_before(std::size_t pos) const;

  std::string_view text_;
  std::vector<std::uint32_t> line_starts_;  // byte offset of each line's first byte
  // Continuation bytes before each kBlock boundary; empty when the text is pure ASCII.
  std::vector<std::uint32_t> block_continuations_;
};

}  // namespace vigil::config::detail
