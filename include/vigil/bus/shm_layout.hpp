#pragma once
/// @file
/// The binary format of a shared-memory port segment (ABI version 2), shared by the process that
/// writes it and the daemon that reads it. docs/reference/shm-segment.md describes every field.
///
/// One segment per component, created when the component joins and never resized:
///
/// ```
///  offset 0            ShmSegmentHeader (768 bytes): format, geometry, who, state, indices
///  mailbox_offset      type_count mailboxes of (8 + record_size) bytes: the latest message of
///                      each type that was dropped, or of a "sticky" type (identity, state
///                      changes, exceptions) whatever happened to it, under a seqlock
///  ring_offset         capacity records of record_size bytes: ShmRecordHeader + payload
///  segment_size        = ring_offset + capacity * record_size
/// ```
///
/// Every multi-byte field is in the machine's byte order, every offset a multiple of 8, the ring
/// and the index lines start on cache lines. Fields that change after creation are accessed only
/// through std::atomic_ref (always lock-free, hence address-free across processes). The indices
/// count records since creation and never wrap (2^64 records); a record's slot is index mod
/// capacity (a power of two), so no index value can make a reader leave the ring.
///
/// Nothing in this header is an OS call: it is plain layout, usable from a fuzz target.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>
#include <type_traits>
#include <variant>

namespace vigil::bus {

/// "VIGILSHM" read as a little-endian 64-bit number.
inline constexpr std::uint64_t kShmMagic = 0x4D48534C49474956ULL;
/// Incremented whenever the layout below changes in any way. 2: the header's constant part is
/// covered by `header_checksum` (ABI 1 had no checksum).
inline constexpr std::uint32_t kShmAbiVersion = 2;
/// The header's first bytes, written once before the segment is published and never again:
/// what `header_checksum` covers.
inline constexpr std::size_t kShmConstantBytes = 512;
/// Bounds the reader accepts (a segment outside them is rejected, not read).
inline constexpr std::uint32_t kShmMaxTypes = 32;
inline constexpr std::uint32_t kShmMaxCapacity = 1U << 16;
inline constexpr std::uint32_t kShmMaxPayload = 4096;
inline constexpr std::uint64_t kShmMaxSegmentSize = 256ULL << 20;
inline constexpr std::size_t kShmCacheLine = 64;

/// Lifecycle of a segment (ShmSegmentHeader::state).
enum class ShmState : std::uint32_t {
  Creating = 0,  ///< being initialised: not to be read yet
  Open = 1,      ///< the component is a member; messages flow
  Closed = 2,    ///< the component left: drain it, then remove the segment
};

/// How the process ended, as it recorded it itself (ShmSegmentHeader::exit_kind).
enum class ShmExit : std::uint32_t {
  Running = 0,   ///< nothing recorded (still running, or died without a chance to record)
  Exited = 1,    ///< exit(exit_code) or return from main
  Signaled = 2,  ///< about to die of signal exit_code (a catchable one: see process_watch.hpp)
};

/// The segment's first 768 bytes.
struct ShmSegmentHeader {
  // --- the format: written once, before `state` becomes Open --------------------------- 0
  std::uint64_t magic;           ///< kShmMagic
  std::uint32_t abi_version;     ///< kShmAbiVersion
  std::uint32_t header_size;     ///< sizeof(ShmSegmentHeader)
  std::uint64_t segment_size;    ///< bytes of the whole segment
  std::uint64_t schema_id;       ///< hash of the message types (ShmSchema::id)
  std::uint32_t type_count;      ///< alternatives of the message variant
  std::uint32_t payload_size;    ///< bytes reserved for a message (largest type, 8-aligned)
  std::uint32_t record_size;     ///< sizeof(ShmRecordHeader) + payload_size
  std::uint32_t capacity;        ///< records in the ring (a power of two)
  std::uint64_t mailbox_offset;  ///< sizeof(ShmSegmentHeader)
  std::uint64_t ring_offset;     ///< mailbox_offset + mailboxes, rounded up to a cache line
  // --- who wrote it: written once --------------------------------------------------------- 64
  std::int32_t pid;
  std::uint32_t uid;              ///< effective uid of the writer
  std::uint64_t start_ticks;      ///< the writer's start time (clock ticks since boot)
  std::int64_t created_unix_ns;   ///< wall clock at creation
  std::uint32_t component_index;  ///< 0, 1, 2... in the order the process's components joined
  std::uint32_t flags;            ///< 0 (reserved)
  char supervisor_name[32];       ///< NUL-terminated: the name given by VIGIL_SUPERVISOR
  char component_name[64];        ///< NUL-terminated (longer names are truncated)
  char process_name[16];          ///< NUL-terminated: the kernel's comm
  char schema_name[48];           ///< NUL-terminated, e.g. "vigil.Message/1"
  char command_line[256];         ///< NUL-terminated, arguments separated by spaces, truncated
  // --- state: atomics ---------------------------------------------------------------------- 512
  alignas(kShmCacheLine) std::uint32_t state;  ///< ShmState
  std::uint32_t exit_kind;                     ///< ShmExit, written by the process's handlers
  std::int32_t exit_code;                      ///< exit code or signal number
  std::uint32_t reserved0;
  std::int64_t daemon_heartbeat_ns;  ///< monotonic time of the daemon's last drain; 0: never
  std::int32_t daemon_pid;           ///< the daemon that drains it; 0: none yet
  std::uint32_t reserved1;
  // --- producer's line --------------------------------------------------------------------- 576
  alignas(kShmCacheLine) std::uint64_t write_index;  ///< records published (release)
  std::uint64_t dropped;                             ///< messages dropped, ring full
  std::uint64_t offered;                             ///< messages pushed or dropped
  // --- consumer's line --------------------------------------------------------------------- 640
  alignas(kShmCacheLine) std::uint64_t read_index;  ///< records consumed (release)
  std::uint64_t drains;                             ///< drains by daemons (statistics)
  // --- integrity: written once ----------------------------------------------------------- 704
  /// shm_header_checksum() of the first kShmConstantBytes, written before `state` becomes Open.
  alignas(kShmCacheLine) std::uint64_t header_checksum;
  std::uint8_t reserved2[56];  ///< 0
};

/// Each record of the ring (and of each mailbox) begins with this.
struct ShmRecordHeader {
  std::uint64_t seq;   ///< 1, 2, 3... per message offered (pushed or dropped): orders mailboxes
  std::uint32_t type;  ///< variant index
  std::uint32_t size;  ///< bytes of the payload used: sizeof the type
};

/// A mailbox: a seqlock version (odd while written) and one record.
struct ShmMailboxHeader {
  std::uint64_t version;
  ShmRecordHeader record;
};

static_assert(std::is_standard_layout_v<ShmSegmentHeader> &&
              std::is_trivially_copyable_v<ShmSegmentHeader>);
static_assert(sizeof(ShmSegmentHeader) == 768, "ABI: the header is 768 bytes");
static_assert(offsetof(ShmSegmentHeader, pid) == 64);
static_assert(offsetof(ShmSegmentHeader, command_line) == 256);
static_assert(offsetof(ShmSegmentHeader, state) == 512);
static_assert(offsetof(ShmSegmentHeader, write_index) == 576);
static_assert(offsetof(ShmSegmentHeader, read_index) == 640);
static_assert(offsetof(ShmSegmentHeader, header_checksum) == 704);
static_assert(offsetof(ShmSegmentHeader, state) == kShmConstantBytes);
static_assert(sizeof(ShmRecordHeader) == 16);
static_assert(sizeof(ShmMailboxHeader) == 24);
// Cross-process atomics must be lock-free (a lock inside the atomic would be per process).
static_assert(std::atomic<std::uint64_t>::is_always_lock_free);
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);
static_assert(std::atomic_ref<std::uint64_t>::is_always_lock_free);
static_assert(std::atomic_ref<std::uint32_t>::is_always_lock_free);
static_assert(std::atomic_ref<std::int64_t>::is_always_lock_free);

/// Sizes derived from (type_count, payload_size, capacity). Plain arithmetic, no validation.
struct ShmGeometry {
  std::uint32_t type_count = 0;
  std::uint32_t payload_size = 0;
  std::uint32_t record_size = 0;
  std::uint32_t capacity = 0;
  std::uint64_t mailbox_offset = 0;
  std::uint64_t mailbox_stride = 0;
  std::uint64_t ring_offset = 0;
  std::uint64_t segment_size = 0;

  /// The geometry of a segment for `type_count` types of at most `payload_size` bytes (rounded
  /// up to 8) and a ring of at least `min_capacity` records (rounded up to a power of two).
  [[nodiscard]] static constexpr ShmGeometry make(std::uint32_t type_count,
                                                  std::uint32_t payload_size,
                                                  std::uint32_t min_capacity) noexcept {
    ShmGeometry g;
    g.type_count = type_count;
    g.payload_size = (payload_size + 7U) & ~7U;
    g.record_size = static_cast<std::uint32_t>(sizeof(ShmRecordHeader)) + g.payload_size;
    std::uint32_t cap = 1;
    while (cap < min_capacity && cap < kShmMaxCapacity) cap <<= 1U;
    g.capacity = cap;
    g.mailbox_offset = sizeof(ShmSegmentHeader);
    g.mailbox_stride = sizeof(std::uint64_t) + g.record_size;
    const std::uint64_t mail_end = g.mailbox_offset + g.mailbox_stride * type_count;
    g.ring_offset = (mail_end + kShmCacheLine - 1) / kShmCacheLine * kShmCacheLine;
    g.segment_size = g.ring_offset + std::uint64_t{g.record_size} * g.capacity;
    return g;
  }
};

/// The checksum of a header's constant part (its first kShmConstantBytes bytes, `h` need not be
/// aligned): FNV-1a over 64-bit words (64 multiply-xor steps, about 0.1 us). A change of any
/// single word always changes it (each step is a bijection of the running value); changes of
/// several words are missed with a probability of about 2^-64. Not a defence against an attacker
/// (who can write the checksum too), but against a wild pointer or a stray memset.
[[nodiscard]] inline std::uint64_t shm_header_checksum(const void* h) noexcept {
  const auto* b = static_cast<const unsigned char*>(h);
  std::uint64_t x = 0xCBF29CE484222325ULL;
  for (std::size_t i = 0; i < kShmConstantBytes; i += 8) {
    std::uint64_t w = 0;
    std::memcpy(&w, b + i, sizeof w);  // the machine's byte order, as every field
    x = (x ^ w) * 0x100000001B3ULL;
  }
  return x;
}

/// The message types a segment carries: how many, how large, and an identity both sides compare
/// (a daemon built with other message definitions rejects the segment instead of misreading it).
struct ShmSchema {
  std::uint64_t id = 0;
  std::uint32_t type_count = 0;
  std::uint32_t payload_size = 0;                   ///< largest type, rounded up to 8
  std::array<std::uint32_t, kShmMaxTypes> sizes{};  ///< sizeof each type
  std::string_view name;                            ///< e.g. "vigil.Message/1" (<= 47 characters)
};

namespace detail {
constexpr std::uint64_t fnv1a(std::uint64_t h, std::uint64_t v) noexcept {
  for (int i = 0; i < 8; ++i) {
    h ^= (v >> (8 * i)) & 0xFFU;
    h *= 0x100000001B3ULL;
  }
  return h;
}
template <class T, class V>
struct VariantIndex;
template <class T, class... A>
struct VariantIndex<T, std::variant<A...>> {
  static constexpr std::uint32_t value = [] {
    constexpr bool same[] = {std::is_same_v<T, A>...};
    for (std::uint32_t i = 0; i < sizeof...(A); ++i) {
      if (same[i]) return i;
    }
    return std::uint32_t{sizeof...(A)};
  }();
  static_assert(value < sizeof...(A), "the type is not an alternative of the variant");
};
template <class V>
struct VariantTypes;
template <class... T>
struct VariantTypes<std::variant<T...>> {
  static constexpr std::uint32_t count = sizeof...(T);
  static constexpr std::array<std::uint32_t, sizeof...(T)> sizes{
      static_cast<std::uint32_t>(sizeof(T))...};
  static constexpr std::array<std::uint32_t, sizeof...(T)> aligns{
      static_cast<std::uint32_t>(alignof(T))...};
};
}  // namespace detail

/// The schema of `Variant` (a std::variant of trivially copyable types), named `name` with a
/// `version` its owner increments when a type changes without changing size. The id hashes the
/// name, version, ABI version and every type's size and alignment.
template <class Variant>
[[nodiscard]] constexpr ShmSchema make_shm_schema(std::string_view name,
                                                  std::uint32_t version) noexcept {
  using Types = detail::VariantTypes<Variant>;
  static_assert(Types::count <= kShmMaxTypes, "too many message types for a shm segment");
  ShmSchema s;
  s.type_count = Types::count;
  std::uint64_t h = 0xCBF29CE484222325ULL;
  for (const char c : name) h = detail::fnv1a(h, static_cast<unsigned char>(c));
  h = detail::fnv1a(h, version);
  h = detail::fnv1a(h, kShmAbiVersion);
  h = detail::fnv1a(h, Types::count);
  std::uint32_t largest = 0;
  for (std::uint32_t i = 0; i < Types::count; ++i) {
    s.sizes[i] = Types::sizes[i];
    largest = Types::sizes[i] > largest ? Types::sizes[i] : largest;
    h = detail::fnv1a(h, Types::sizes[i]);
    h = detail::fnv1a(h, Types::aligns[i]);
  }
  s.payload_size = (largest + 7U) & ~7U;
  s.id = h;
  s.name = name;
  return s;
}

/// The bit of each of `T...` in a mask over `Variant`'s alternatives (for sticky types).
template <class Variant, class... T>
[[nodiscard]] constexpr std::uint32_t shm_type_mask() noexcept {
  return ((std::uint32_t{1} << detail::VariantIndex<T, Variant>::value) | ... | 0U);
}

}  // namespace vigil::bus
