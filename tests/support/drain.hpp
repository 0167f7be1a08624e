#pragma once
// Pops everything a port holds, for tests that check what a component sent.
#include <vector>

#include "vigil/bus/port.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::test {

template <class PortT>
std::vector<task::Message> drain(PortT& port) {
  std::vector<task::Message> out;
  task::Message buf[64];
  for (;;) {
    const auto n = port.pop(buf, 64);
    if (n == 0) break;
    out.insert(out.end(), buf, buf + n);
  }
  return out;
}

template <class T>
std::vector<T> only(const std::vector<task::Message>& ms) {
  std::vector<T> out;
  for (const auto& m : ms) {
    if (const auto* p = std::get_if<T>(&m)) out.push_back(*p);
  }
  return out;
}

/// The cycle samples among `ms`, without the totals-only repeats sent on stop and leave.
inline std::vector<task::CycleSample> cycles_of(const std::vector<task::Message>& ms) {
  std::vector<task::CycleSample> out;
  for (const auto& s : only<task::CycleSample>(ms)) {
    if (!s.totals_only) out.push_back(s);
  }
  return out;
}

}  // namespace vigil::test
