#pragma once
// Mutated input for the log readers' robustness tests (candump, TRC): lines of a real format
// with random edits, and a reader's pass over them.
#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <string_view>
#include <vector>

namespace vigil::test {

/// `lines` lines, each a line of `seeds` picked at random with 1 to 3 edits: a character
/// replaced, a character inserted, 1 to 3 bytes erased, or the line cut short. The characters
/// come from `alphabet`, or one time in eight are any byte. The same `seed`, the same text.
inline std::string mutated_lines(const std::vector<std::string>& seeds, std::string_view alphabet,
                                 int lines, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::string text;
  for (int i = 0; i < lines; ++i) {
    std::string l = seeds[rng() % seeds.size()];
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int k = 0; k < edits && !l.empty(); ++k) {
      const std::size_t at = rng() % l.size();
      const char c =
          rng() % 8 == 0 ? static_cast<char>(rng() % 256) : alphabet[rng() % alphabet.size()];
      switch (rng() % 4) {
        case 0:
          l[at] = c;
          break;
        case 1:
          l.insert(l.begin() + static_cast<std::ptrdiff_t>(at), c);
          break;
        case 2:
          l.erase(at, 1 + rng() % 3);
          break;
        default:
          l.resize(at);
          break;
      }
    }
    text += l;
    text += '\n';
  }
  return text;
}

/// What a reader made of its whole input: the frames it returned, how many of them were
/// invalid (none should be), and whether every call succeeded (an I/O error is a failure).
struct ReadThrough {
  std::uint64_t frames = 0;
  std::uint64_t invalid = 0;
  bool every_call_ok = true;
};

/// Reads `reader` (CandumpReader, TrcReader: next() gives an expected optional entry) to its end.
template <class Reader>
ReadThrough read_through(Reader& reader) {
  ReadThrough r;
  for (;;) {
    auto e = reader.next();
    if (!e.has_value()) {
      r.every_call_ok = false;
      break;
    }
    if (!*e) break;
    ++r.frames;
    if (!(*e)->frame.valid()) ++r.invalid;
  }
  return r;
}

}  // namespace vigil::test
