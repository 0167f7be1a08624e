#pragma once
/// @file
/// The process side of supervision across processes: `ShmSession` creates one segment per
/// component that joins (named /vigil.<supervisor>.<pid>.<index>, owner-only), `ShmPort<Variant>`
/// owns one (mapping + producer), and `ShmPorts<Variant>` is what a Registry holds to place its
/// ports in shared memory. Selection: `shm_options_from_environment()` reads VIGIL_SUPERVISOR.
///
/// The session also records how the process ends in every live segment (exit code, or the
/// catchable signal that kills it; platform::install_exit_recorder), and removes its segments at
/// a normal exit when no daemon drains them. A segment whose component leaves is closed; the
/// daemon drains and removes it, or the process removes it itself when no daemon has drained it
/// for kShmOrphanAfter.
///
/// Not RT-safe (join and leave time), except what ShmProducer documents.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "vigil/bus/shm_layout.hpp"
#include "vigil/bus/shm_port.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/shm.hpp"

namespace vigil::bus {

/// A segment that no daemon drained for this long is considered unattended: the process removes
/// it itself when its component leaves or the process exits.
inline constexpr Nanos kShmOrphanAfter = 2 * kNanosPerSecond;

/// Where and how a process's ports go to shared memory.
struct ShmOptions {
  /// The supervisor's name (1..31 of [A-Za-z0-9_-]): `vigil supervise --name` reads it.
  std::string name;
  /// A group given read-write access (mode 0660); empty: owner only (0600).
  std::string group;
  /// Message types mirrored in their mailbox on every push (shm_type_mask).
  std::uint32_t sticky_types = 0;
  /// Told when a segment cannot be created (the component then stays in-process). Default:
  /// one line on stderr.
  std::function<void(const std::string&)> on_error;
};

/// Reads VIGIL_SUPERVISOR (the name) and VIGIL_SUPERVISOR_GROUP (optional group). nullopt when
/// VIGIL_SUPERVISOR is unset or empty; an error when it is not a valid name.
[[nodiscard]] expected<std::optional<ShmOptions>, Error> shm_options_from_environment();

/// One component's segment: owns the mapping and the name. On destruction the segment is
/// marked closed, removed from the process's exit records, and unlinked when no daemon drains
/// it; otherwise the daemon removes it after draining.
class ShmSegment {
 public:
  ShmSegment(platform::SharedMemory memory, ShmGeometry geometry);
  ~ShmSegment();
  ShmSegment(const ShmSegment&) = delete;
  ShmSegment& operator=(const ShmSegment&) = delete;

  [[nodiscard]] void* data() const noexcept { return memory_.data(); }
  [[nodiscard]] const ShmGeometry& geometry() const noexcept { return geometry_; }
  [[nodiscard]] const std::string& name() const noexcept { return memory_.name(); }

 private:
  platform::SharedMemory memory_;
  ShmGeometry geometry_;
  int slot_ = -1;  // index in the process's exit-record table
};

/// Creates the segments of one process under one supervisor name. Thread-safe.
class ShmSession {
 public:
  /// A session for `options.name` and message `schema`. Fails for an invalid name or group.
  static expected<std::shared_ptr<ShmSession>, Error> open(ShmOptions options, ShmSchema schema);

  /// Creates and initialises the segment of component `component` with a ring of at least
  /// `capacity` records. Not RT-safe.
  expected<std::unique_ptr<ShmSegment>, Error> create(std::string_view component,
                                                      std::uint32_t capacity);

  [[nodiscard]] const ShmOptions& options() const noexcept { return options_; }
  [[nodiscard]] const ShmSchema& schema() const noexcept { return schema_; }
  /// Segments created so far by this session.
  [[nodiscard]] std::uint32_t created() const;

  /// Reports an error through options().on_error (or stderr).
  void report(const std::string& message) const;

 private:
  ShmSession(ShmOptions options, ShmSchema schema);
  ShmOptions options_;
  ShmSchema schema_;
  mutable std::mutex mutex_;
  std::uint32_t next_index_ = 0;
};

/// A component's port in shared memory: its segment and the producer writing it.
template <class Variant>
class ShmPort {
 public:
  ShmPort(std::unique_ptr<ShmSegment> segment, std::uint32_t sticky)
      : segment_(std::move(segment)), producer_(segment_->data(), segment_->geometry(), sticky) {}

  /// The producer end (RT-safe pushes; one thread).
  [[nodiscard]] ShmProducer<Variant>& producer() noexcept { return producer_; }
  [[nodiscard]] const ShmSegment& segment() const noexcept { return *segment_; }

  /// At leave: pushes `words` (or keeps them in their mailboxes when the ring is full) and
  /// closes the segment. Producer's thread (or after it stopped). Not RT-safe.
  template <class Range>
  void close(const Range& words) noexcept {
    for (const Variant& w : words) {
      if (!producer_.push(w)) producer_.drop(w, dropped_at_close_);
    }
    producer_.close();
  }
  /// The port's drop count, so that close() keeps the segment's count exact.
  void set_dropped(std::uint64_t dropped) noexcept { dropped_at_close_ = dropped; }

 private:
  std::unique_ptr<ShmSegment> segment_;
  ShmProducer<Variant> producer_;
  std::uint64_t dropped_at_close_ = 0;
};

/// What a Registry holds to place its ports in shared memory. Thread-safe.
template <class Variant>
class ShmPorts {
 public:
  explicit ShmPorts(std::shared_ptr<ShmSession> session) : session_(std::move(session)) {}

  /// Opens the shared-memory port of component `name` (capacity at least `capacity`), or
  /// returns null after reporting why (the component then uses an in-process port).
  std::shared_ptr<ShmPort<Variant>> open(std::string_view name, std::size_t capacity) {
    auto seg = session_->create(
        name, static_cast<std::uint32_t>(std::min<std::size_t>(capacity, kShmMaxCapacity)));
    if (!seg) {
      session_->report("vigil: component '" + std::string(name) +
                       "' is supervised in-process only: " + seg.error().message);
      return nullptr;
    }
    return std::make_shared<ShmPort<Variant>>(std::move(*seg), session_->options().sticky_types);
  }

  [[nodiscard]] const ShmSession& session() const noexcept { return *session_; }

 private:
  std::shared_ptr<ShmSession> session_;
};

/// Places `registry`'s future ports in shared memory as VIGIL_SUPERVISOR says (nothing when it
/// is unset), with `schema` and `sticky` types. Returns false and reports on stderr when the
/// variable is invalid. Not RT-safe; call before components join.
template <class Registry>
bool place_from_environment(Registry& registry, const ShmSchema& schema, std::uint32_t sticky) {
  auto opts = shm_options_from_environment();
  if (!opts) {
    std::fprintf(stderr, "vigil: %s; components are supervised in-process\n",
                 opts.error().message.c_str());
    return false;
  }
  std::optional<ShmOptions>& chosen = *opts;
  if (!chosen.has_value()) return true;
  chosen->sticky_types = sticky;
  auto session = ShmSession::open(std::move(*chosen), schema);
  if (!session) {
    std::fprintf(stderr, "vigil: %s; components are supervised in-process\n",
                 session.error().message.c_str());
    return false;
  }
  registry.place_in_shared_memory(
      std::make_shared<typename Registry::ShmPortsType>(std::move(*session)));
  return true;
}

}  // namespace vigil::bus
