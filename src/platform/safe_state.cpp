#include "vigil/safe_state.hpp"

#include <mutex>

namespace vigil {

namespace detail {
constinit std::atomic<std::uint64_t> safe_state_generation{0};
}  // namespace detail

namespace {
std::mutex& request_mutex() {
  static std::mutex m;
  return m;
}
SafeStateRequest& standing() {
  static SafeStateRequest r;
  return r;
}
std::uint64_t requests = 0;  // under request_mutex()
}  // namespace

bool request_safe_state(std::string_view reason) {
  const Nanos now = platform::now_ns();
  const std::lock_guard lock(request_mutex());
  if (standing().generation != 0) return false;
  standing() = {.generation = ++requests, .requested_ns = now, .reason = std::string(reason)};
  // Release: whoever sees the flag and then calls safe_state() sees its reason.
  detail::safe_state_generation.store(requests, std::memory_order_release);
  return true;
}

bool clear_safe_state() {
  const std::lock_guard lock(request_mutex());
  if (standing().generation == 0) return false;
  standing() = {};
  detail::safe_state_generation.store(0, std::memory_order_release);
  return true;
}

SafeStateRequest safe_state() {
  const std::lock_guard lock(request_mutex());
  return standing();
}

}  // namespace vigil
