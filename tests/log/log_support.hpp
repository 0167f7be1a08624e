#pragma once
// A bare source bound to a small port, and a decoder: the RT side of logging without a task.
#include <string>
#include <vector>

#include "vigil/log/log.hpp"
#include "vigil/task/messages.hpp"

namespace vigil::test {

/// A source on its own port, inside a cycle for the lifetime of the object.
template <std::size_t N = 64>
struct LogBench {
  explicit LogBench(std::string name = "bench", std::uint64_t cycle = 1, Nanos time = 1000)
      : source(std::move(name), &port) {
    source.enter(cycle, time);
  }
  ~LogBench() { source.leave(); }
  LogBench(const LogBench&) = delete;
  LogBench& operator=(const LogBench&) = delete;

  /// Moves to another cycle (number and start time).
  void at(std::uint64_t cycle, Nanos time) {
    source.leave();
    source.enter(cycle, time);
  }

  /// Every record waiting in the port (other messages are skipped).
  std::vector<log::LogRecord> records() {
    std::vector<log::LogRecord> out;
    task::Message m;
    while (port.pop(&m, 1) == 1) {
      if (const auto* r = std::get_if<log::LogRecord>(&m)) out.push_back(*r);
    }
    return out;
  }
  /// The text of the only record waiting (fails the test if there is not exactly one).
  std::string text() {
    const auto rs = records();
    if (rs.size() != 1) return "<" + std::to_string(rs.size()) + " records>";
    return decode(rs[0]);
  }
  static std::string decode(const log::LogRecord& r) {
    std::string s;
    r.site->decode(s, *r.site, r);
    return s;
  }

  Port<task::Message, N> port;
  log::PortSource<task::Message, N> source;
};

}  // namespace vigil::test
