#pragma once
/// @file
/// POSIX shared memory for supervision across processes: creating, opening, listing and removing
/// named segments (/dev/shm on Linux), watching the directory for new segments, and copying out
/// of a mapping that another process may shrink (a bus error becomes a returned failure).
///
/// None of these functions is RT-safe: they are called when a component joins (creation) and by
/// the supervising daemon. Once a segment is mapped, the real-time side only reads and writes
/// memory. Cobalt uses the same Linux calls (segments are set up from non-RT context).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::platform {

/// What the file system says about a segment (fstat of its descriptor).
struct ShmFileInfo {
  std::uint32_t uid = 0;   ///< owner
  std::uint32_t gid = 0;   ///< group
  std::uint32_t mode = 0;  ///< permission bits (e.g. 0600)
  std::uint64_t size = 0;  ///< bytes
  std::uint64_t inode = 0;
  std::uint64_t device = 0;
};

/// How a segment is created.
struct ShmCreateOptions {
  /// Permission bits. 0600 (owner only) unless a group is named; with a group, 0660.
  std::uint32_t mode = 0600;
  /// A group (name or number) to give read-write access to; empty for owner only.
  std::string group;
};

/// A mapped segment (read-write, MAP_SHARED). Move-only; unmaps on destruction (the name stays
/// until unlink()). Not RT-safe.
class SharedMemory {
 public:
  SharedMemory() = default;
  SharedMemory(SharedMemory&& o) noexcept;
  SharedMemory& operator=(SharedMemory&& o) noexcept;
  SharedMemory(const SharedMemory&) = delete;
  SharedMemory& operator=(const SharedMemory&) = delete;
  ~SharedMemory();

  /// Creates segment `name` ("/vigil.x.123": a leading '/', no other '/') of `size` bytes,
  /// zero-filled, with the options' permissions, and maps it. Fails if it exists (EEXIST) or
  /// cannot be created, sized or mapped; the error names the segment and the call.
  static expected<SharedMemory, Error> create(const std::string& name, std::size_t size,
                                              const ShmCreateOptions& options = {});

  /// Opens and maps existing segment `name` read-write, as large as the file is now (fstat).
  /// `max_size` bounds what is mapped: a larger file is refused. Fails with a message naming
  /// the segment when it does not exist, cannot be opened or is empty.
  static expected<SharedMemory, Error> open(const std::string& name, std::size_t max_size);

  [[nodiscard]] void* data() const noexcept { return data_; }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  /// The segment's file information at creation or opening.
  [[nodiscard]] const ShmFileInfo& info() const noexcept { return info_; }
  [[nodiscard]] bool mapped() const noexcept { return data_ != nullptr; }

  /// Removes the name (the mapping stays valid until destruction). Errors other than "already
  /// gone" are returned.
  expected<void, Error> unlink() const;

  /// Re-reads the file's information (fstat on a descriptor kept open): e.g. to see that the
  /// file was shrunk below the mapping.
  [[nodiscard]] expected<ShmFileInfo, Error> stat() const;

 private:
  void reset() noexcept;
  void* data_ = nullptr;
  std::size_t size_ = 0;
  int fd_ = -1;
  std::string name_;
  ShmFileInfo info_;
};

/// Removes segment `name`. Succeeds when it is already gone.
expected<void, Error> unlink_shared_memory(const std::string& name);

/// Names ("/vigil.x.123") of the segments whose name begins with `prefix` (given without the
/// leading '/'), sorted. Empty when the directory cannot be read.
[[nodiscard]] std::vector<std::string> list_shared_memory(std::string_view prefix);

/// The user id of the calling process (effective).
[[nodiscard]] std::uint32_t effective_uid() noexcept;

/// The group id of group `name_or_number`, if it exists.
[[nodiscard]] std::optional<std::uint32_t> group_id(const std::string& name_or_number);

/// Watches the shared-memory directory for segments created or removed (inotify), so that a
/// daemon notices a new process at once instead of listing the directory every cycle.
class ShmDirectoryWatch {
 public:
  ShmDirectoryWatch() = default;
  ShmDirectoryWatch(ShmDirectoryWatch&& o) noexcept;
  ShmDirectoryWatch& operator=(ShmDirectoryWatch&& o) noexcept;
  ShmDirectoryWatch(const ShmDirectoryWatch&) = delete;
  ShmDirectoryWatch& operator=(const ShmDirectoryWatch&) = delete;
  ~ShmDirectoryWatch();

  /// Starts watching. Fails when inotify is unavailable (the caller then lists periodically).
  static expected<ShmDirectoryWatch, Error> open();

  /// A descriptor that becomes readable when something changed (for wait_readable()).
  [[nodiscard]] int fd() const noexcept { return fd_; }

  /// Consumes the pending notifications; true when any file whose name starts with `prefix`
  /// (every file when empty) was created, renamed or removed, or the queue overflowed (list
  /// again). A daemon passes its segments' prefix, so that other programs' files in the
  /// directory (other daemons', tracers') do not make it list the directory each cycle.
  bool consume(std::string_view prefix = {}) noexcept;

 private:
  int fd_ = -1;
};

/// Runs `fn(ctx)` and returns true, or returns false if it raised SIGBUS by touching a mapping
/// beyond the end of its file (another process truncated the file after it was mapped). The
/// first call installs a SIGBUS handler; a SIGBUS outside such a call goes to the handler that
/// was there before (or the default action). `fn` must only read and write memory: it may be
/// abandoned half-way (no destructor runs, nothing may be allocated or locked). Thread-safe
/// (per-thread state). Not RT-safe: the daemon's guard around one segment's drain (~20 ns).
bool run_guarded(void (*fn)(void* ctx) noexcept, void* ctx) noexcept;

}  // namespace vigil::platform
