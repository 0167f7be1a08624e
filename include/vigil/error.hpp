#pragma once
/// @file
/// `vigil::Error`: the error type carried by `vigil::expected` off the real-time path.

#include <string>
#include <utility>

namespace vigil {

/// An error from a fallible operation that is not on the real-time path.
///
/// `code` is an errno value where the operating system reported one (0 otherwise) so that callers
/// can react to, e.g., EPERM when SCHED_FIFO is refused; `message` says what failed and why in
/// words a user can act on ("pthread_create(SCHED_FIFO, priority 80): Operation not permitted").
struct Error {
  int code = 0;
  std::string message;

  Error() = default;
  Error(int c, std::string m) : code(c), message(std::move(m)) {}
  explicit Error(std::string m) : message(std::move(m)) {}
};

}  // namespace vigil
