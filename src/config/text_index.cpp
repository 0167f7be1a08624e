#include "config/text_index.hpp"

#include <algorithm>

namespace vigil::config::detail {
namespace {
bool is_continuation(char c) { return (static_cast<unsigned char>(c) & 0xC0) == 0x80; }
}  // namespace

TextIndex::TextIndex(std::string_view text) : text_(text) {
  line_starts_.push_back(0);
  bool ascii = true;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\n') line_starts_.push_back(static_cast<std::uint32_t>(i + 1));
    if (is_continuation(text[i])) ascii = false;
  }
  if (ascii) return;
  block_continuations_.reserve(text.size() / kBlock + 1);
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (i % kBlock == 0) block_continuations_.push_back(count);
    if (is_continuation(text[i])) ++count;
  }
  if (text.size() % kBlock == 0) block_continuations_.push_back(count);
}

std::size_t TextIndex::continuations_before(std::size_t pos) const {
  if (block_continuations_.empty()) return 0;
  const std::size_t block = pos / kBlock;
  std::size_t count = block_continuations_[block];
  for (std::size_t i = block * kBlock; i < pos; ++i) count += is_continuation(text_[i]) ? 1 : 0;
  return count;
}

std::pair<int, int> TextIndex::locate(const YAML::Mark& mark) const {
  if (mark.is_null() || mark.line < 0 || mark.column < 0) return {0, 0};
  const int line = mark.line + 1;
  int column = mark.column + 1;
  if (mark.pos >= 0 && static_cast<std::size_t>(mark.pos) <= text_.size()) {
    const auto pos = static_cast<std::size_t>(mark.pos);
    // The last line start at or before pos (a '\n' at pos itself belongs to that line).
    const auto next = std::upper_bound(line_starts_.begin(), line_starts_.end(), pos);
    const std::size_t start = *(next - 1);
    if (pos - start == static_cast<std::size_t>(mark.column)) {
      const std::size_t chars =
          (pos - start) - (continuations_before(pos) - continuations_before(start));
      column = static_cast<int>(chars) + 1;
    }
  }
  return {line, column};
}

}  // namespace vigil::config::detail
