#pragma once
/// @file
/// `ReadySet`: descriptors waited on together (Linux epoll), for a thread that waits on many
/// (the `vigil supervise` daemon: every supervised process's pidfd and its /dev/shm watch).
/// Not RT-safe (system calls).
#include <cstddef>
#include <cstdint>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::platform {

/// Descriptors waited on together (Linux epoll): each is added and removed once (a system call
/// each), and a wait costs what is ready, not what is watched (`wait_readable` over n
/// descriptors costs n every call: 100 pidfds made two polls per supervisor cycle cost the daemon
/// about 9 % of its CPU). Level-triggered: a descriptor stays ready until its cause is consumed.
/// add, remove and wait may be called from different threads. Move-only.
class ReadySet {
 public:
  ReadySet() = default;
  ReadySet(ReadySet&& o) noexcept;
  ReadySet& operator=(ReadySet&& o) noexcept;
  ReadySet(const ReadySet&) = delete;
  ReadySet& operator=(const ReadySet&) = delete;
  ~ReadySet();
  /// An empty set. Fails with the system's error (no epoll, out of descriptors).
  static expected<ReadySet, Error> open();
  /// Watches `fd` for readability (and hang-up, error); `tag` comes back from wait(). A closed
  /// descriptor leaves the set by itself.
  expected<void, Error> add(int fd, std::uint64_t tag) noexcept;
  /// Stops watching `fd` (nothing when it is not watched).
  void remove(int fd) noexcept;
  /// Waits until a watched descriptor is ready or the monotonic clock reaches `deadline_ns` (0 or
  /// a past deadline: no wait), then writes the tags of up to `max` ready descriptors to `tags`.
  /// Returns how many (0 at the deadline), or -errno. EINTR is resumed until the deadline.
  int wait(Nanos deadline_ns, std::uint64_t* tags, std::size_t max) noexcept;
  [[nodiscard]] bool valid() const noexcept { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

}  // namespace vigil::platform
