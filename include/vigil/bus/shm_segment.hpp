#pragma once
/// @file
/// Creating and validating shared-memory port segments (format: shm_layout.hpp), and the
/// reader's raw access to one validated segment. Not a message type in sight: the message
/// variant enters only through its `ShmSchema`; decoding is in shm_port.hpp.
///
/// Safety of the reader (the daemon): a segment is another process's memory and may be
/// truncated, corrupted or hostile. Everything read from it is first copied out, then checked
/// (never checked in place and read again); geometry is taken from the reader's own expectation
/// and compared with the header, never trusted; ring positions are index mod capacity; indices
/// that are not monotonic or further apart than the capacity reject the segment; every access to
/// the mapping runs under platform::run_guarded, so a file shrunk after mapping is an error, not a
/// bus error. A rejected segment is reported with the field at fault and never read again.
///
/// Not RT-safe (creation happens when a component joins; the rest is the daemon's).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "vigil/bus/shm_layout.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/shm.hpp"

namespace vigil::bus {

/// Why a segment is rejected: the header field (or "file", "ring", "record", "mailbox") and
/// what is wrong with it, in words.
struct ShmError {
  std::string field;
  std::string message;

  /// "field: message".
  [[nodiscard]] std::string to_string() const { return field + ": " + message; }
};

/// What a reader requires of a segment.
struct ShmExpectation {
  ShmSchema schema;
  /// The supervisor name the segment must carry; empty accepts any.
  std::string_view supervisor_name;
};

/// What a valid segment says about itself: copies, safe to keep.
struct ShmSegmentInfo {
  ShmGeometry geometry;
  std::int32_t pid = 0;
  std::uint32_t uid = 0;
  std::uint64_t start_ticks = 0;
  std::int64_t created_unix_ns = 0;
  std::uint32_t component_index = 0;
  std::string supervisor_name;
  std::string component_name;
  std::string process_name;
  std::string schema_name;
  std::string command_line;
};

/// The state fields of a segment, read at one moment (atomics, acquire).
struct ShmLiveState {
  ShmState state = ShmState::Creating;
  ShmExit exit_kind = ShmExit::Running;
  std::int32_t exit_code = 0;
  std::uint64_t write_index = 0;
  std::uint64_t read_index = 0;
  std::uint64_t dropped = 0;
  std::uint64_t offered = 0;
  std::int64_t daemon_heartbeat_ns = 0;
  std::int32_t daemon_pid = 0;
  std::uint64_t drains = 0;
};

/// Validates a copy of a segment's header against `e` for a segment of `size` bytes: magic, ABI
/// version, header size, schema (id, type count, payload size, name), geometry (capacity a power
/// of two within bounds, record size, offsets, total size equal to `size`), identity (pid > 0,
/// every string NUL-terminated, component name not empty, supervisor name as expected), state,
/// exit record and indices (read <= write <= read + capacity). Pure function: the fuzz target's
/// entry point. A segment still in ShmState::Creating is an error with field "state" (retry).
[[nodiscard]] expected<ShmSegmentInfo, ShmError> validate_shm_header(const ShmSegmentHeader& header,
                                                                     std::uint64_t size,
                                                                     const ShmExpectation& e);

/// The name of the header field at byte `offset` ("magic", "component_name", "reserved2"...).
[[nodiscard]] const char* shm_header_field(std::size_t offset) noexcept;

/// The first field of the constant part (the first kShmConstantBytes) or of `header_checksum`
/// in which `a` and `b` differ; null when they agree there.
[[nodiscard]] const char* shm_constant_difference(const ShmSegmentHeader& a,
                                                  const ShmSegmentHeader& b) noexcept;

/// Validates the segment image of `size` bytes at `bytes` (copies the header out first; an image
/// shorter than the header is an error). Reads nothing outside [bytes, bytes + size).
[[nodiscard]] expected<ShmSegmentInfo, ShmError> validate_shm_image(const void* bytes,
                                                                    std::size_t size,
                                                                    const ShmExpectation& e);

/// Checks what the file system says: owned by `uid`, not accessible to others, a group may read
/// and write only if `allow_group`, size within kShmMaxSegmentSize.
[[nodiscard]] expected<void, ShmError> check_shm_file(const platform::ShmFileInfo& file,
                                                      std::uint32_t uid, bool allow_group);

/// Who creates a segment (written into its header).
struct ShmIdentity {
  std::string_view supervisor_name;
  std::string_view component_name;
  std::uint32_t component_index = 0;
  std::int32_t pid = 0;
  std::uint32_t uid = 0;
  std::uint64_t start_ticks = 0;
  std::int64_t created_unix_ns = 0;
  std::string_view process_name;
  std::string_view command_line;
};

/// Writes a complete header for geometry `g` into the zero-filled segment at `base` (at least
/// g.segment_size bytes) and publishes it (state Open, release). Producer side, at join.
void init_shm_segment(void* base, const ShmGeometry& g, const ShmSchema& schema,
                      const ShmIdentity& who) noexcept;

/// "/vigil.<supervisor>.<pid>.<index>": the name of a component's segment.
[[nodiscard]] std::string shm_segment_name(std::string_view supervisor, std::int32_t pid,
                                           std::uint32_t index);
/// "vigil.<supervisor>.": the prefix of every segment of a supervisor (for listing).
[[nodiscard]] std::string shm_segment_prefix(std::string_view supervisor);
/// Whether `name` is a valid supervisor name: 1 to 31 characters among [A-Za-z0-9_-].
[[nodiscard]] bool valid_supervisor_name(std::string_view name) noexcept;

/// The reader's access to one validated segment. Every method touches the mapping only under
/// platform::run_guarded and validates what it copied. Daemon thread only.
class ShmRingReader {
 public:
  ShmRingReader() = default;
  /// Reads the segment at `base`, whose header validated to geometry `g` (base must stay mapped
  /// for the reader's life). Starts at the read index the segment holds (a daemon restarted
  /// continues where the previous one stopped).
  ShmRingReader(void* base, const ShmGeometry& g) noexcept
      : base_(static_cast<std::byte*>(base)), g_(g) {}

  /// The state fields, validated: state and exit kind in range; the write index neither behind
  /// what this reader consumed nor more than the capacity ahead; the shared read index equal to
  /// this reader's; `offered` at least write_index - 1 and `dropped` at most offered + 1 (the
  /// bounds the writer's store order guarantees). An error means the segment is corrupt (or was
  /// truncated).
  [[nodiscard]] expected<ShmLiveState, ShmError> live() const noexcept;

  /// Re-verifies what the writer set once: copies the header out and checks that its constant
  /// part still matches its checksum and `reference` (the copy validated at open; the error
  /// names the first field that differs), that the reserved fields are still zero and that
  /// `header_checksum` is unchanged. The copy is left in `out` when not null.
  [[nodiscard]] expected<void, ShmError> verify_header(const ShmSegmentHeader& reference,
                                                       ShmSegmentHeader* out) const noexcept;

  /// Takes the read index from the segment (call once before pop_each; validated).
  [[nodiscard]] expected<void, ShmError> attach() noexcept;

  /// Called by pop_each() for each record, in place in the ring, oldest first. It copies out
  /// what it keeps (the ring slot is the producer's again once the read index moves) and must
  /// neither throw nor own anything that needs a destructor: it runs where a bus error (a
  /// truncated mapping) is caught by a long jump. Returning false stops before that record,
  /// which is not consumed.
  using RecordFn = bool (*)(void* ctx, const std::byte* record) noexcept;

  /// Hands up to `max` records, oldest first, to `fn` in place, then advances the read index
  /// past those it accepted. Returns how many were accepted, or an error when the indices became
  /// inconsistent or the mapping shrank.
  [[nodiscard]] expected<std::size_t, ShmError> pop_each(std::size_t max, RecordFn fn,
                                                         void* ctx) noexcept;

  /// Copies mailbox `type` (record_size bytes: ShmRecordHeader + payload) into `out`. Returns
  /// false when it is empty (seq 0), being written (retried a few times) or unreadable.
  [[nodiscard]] bool read_mailbox(std::uint32_t type, std::byte* out) const noexcept;

  /// Records that daemon `pid` drained the segment at monotonic time `now`.
  void heartbeat(std::int64_t now, std::int32_t pid) noexcept;

  /// Hints the CPU to bring in what the next `live()` of the segment mapped at `base` reads (the
  /// state and write-index lines of the header), without reading the reader itself. A hint only:
  /// it reads nothing, cannot fault, and is harmless on a segment that shrank.
  static void prefetch_state(const void* base) noexcept {
    const auto* b = static_cast<const std::byte*>(base);
    __builtin_prefetch(b + kStateOffset, 1);  // written too: the heartbeat
    __builtin_prefetch(b + kWriteIndexOffset);
  }
  /// Hints the CPU to bring in the first `lines` cache lines of the records waiting at the read
  /// index, and the read index's line (written by the drain). A hint only, as above.
  void prefetch_records(std::size_t lines) const noexcept {
    __builtin_prefetch(base_ + kReadIndexOffset, 1);
    if (g_.capacity == 0) return;
    const std::byte* rec = base_ + g_.ring_offset + (read_ & (g_.capacity - 1)) * g_.record_size;
    for (std::size_t i = 0; i < lines; ++i) __builtin_prefetch(rec + 64 * i);
  }

  /// Records consumed by this reader (its read index).
  [[nodiscard]] std::uint64_t read_index() const noexcept { return read_; }
  [[nodiscard]] const ShmGeometry& geometry() const noexcept { return g_; }

 private:
  static constexpr std::size_t kStateOffset = offsetof(ShmSegmentHeader, state);
  static constexpr std::size_t kWriteIndexOffset = offsetof(ShmSegmentHeader, write_index);
  static constexpr std::size_t kReadIndexOffset = offsetof(ShmSegmentHeader, read_index);
  std::byte* base_ = nullptr;
  ShmGeometry g_;
  std::uint64_t read_ = 0;
  bool attached_ = false;  // from attach() on, the shared read index is this reader's
};

}  // namespace vigil::bus
