// Fuzz target: the candump log reader (vigil can-stats, LogReplay) on arbitrary bytes, in both
// malformed-line modes, and the frame field parser (cansend syntax) on the first line.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>

#include "vigil/can/log/candump.hpp"

namespace {
void check(bool ok) {
  if (!ok) __builtin_trap();
}

void read_all(const std::string& text, vigil::can::OnMalformed mode) {
  std::istringstream in(text);
  vigil::can::ReaderOptions options;
  options.on_malformed = mode;
  options.max_kept_errors = 4;
  vigil::can::CandumpReader reader(in, "fuzz.log", options);
  for (std::size_t n = 0;; ++n) {
    check(n <= text.size());  // at most one frame per byte: the reader always advances
    auto entry = reader.next();
    if (!entry) {
      check(mode == vigil::can::OnMalformed::Stop);
      check(!entry.error().message.empty());
      break;
    }
    if (!*entry) break;
    const vigil::can::Frame& f = (*entry)->frame;
    check(f.length <= 64);
    check(f.bus < reader.interfaces().size());
  }
  check(reader.errors().size() <= 4);
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  read_all(text, vigil::can::OnMalformed::Skip);
  read_all(text, vigil::can::OnMalformed::Stop);
  const std::string_view first = std::string_view(text).substr(0, text.find('\n'));
  if (auto frame = vigil::can::parse_candump_frame(first)) check(frame->length <= 64);
  return 0;
}
