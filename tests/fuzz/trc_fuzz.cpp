// Fuzz target: the PEAK TRC trace reader (versions 1.0 to 2.1) on arbitrary bytes, in both
// malformed-line modes.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "vigil/can/log/trc.hpp"

namespace {
void check(bool ok) {
  if (!ok) __builtin_trap();
}

void read_all(const std::string& text, vigil::can::OnMalformed mode) {
  std::istringstream in(text);
  vigil::can::ReaderOptions options;
  options.on_malformed = mode;
  options.max_kept_errors = 4;
  vigil::can::TrcReader reader(in, "fuzz.trc", options);
  for (std::size_t n = 0;; ++n) {
    check(n <= text.size());
    auto entry = reader.next();
    if (!entry) {
      check(!entry.error().message.empty());
      break;
    }
    if (!*entry) break;
    check((*entry)->frame.length <= 64);
  }
  check(reader.errors().size() <= 4);
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  read_all(text, vigil::can::OnMalformed::Skip);
  read_all(text, vigil::can::OnMalformed::Stop);
  return 0;
}
