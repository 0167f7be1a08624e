// Segment creation and validation; the daemon's guarded raw access to a segment.
#include "vigil/bus/shm_segment.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <optional>

namespace vigil::bus {

namespace {

template <class T>
std::atomic_ref<T> at(T& field) noexcept {
  return std::atomic_ref<T>(field);
}

ShmError err(std::string field, std::string message) {
  return ShmError{std::move(field), std::move(message)};
}

// A NUL-terminated string stored in `a`, or an error when it has no terminator.
template <std::size_t N>
expected<std::string, ShmError> text(const char (&a)[N], const char* field) {
  const void* nul = std::memchr(a, '\0', N);
  if (nul == nullptr) {
    return unexpected<ShmError>(
        err(field, fmt::format("not NUL-terminated within its {} bytes", N)));
  }
  return std::string(a, static_cast<const char*>(nul));
}

template <std::size_t N>
void put_text(char (&a)[N], std::string_view s) noexcept {
  const std::size_t n = std::min(s.size(), N - 1);
  if (n > 0) std::memcpy(a, s.data(), n);
  a[n] = '\0';
}

bool valid_name_char(char c) noexcept {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '-';
}

ShmError indices_error(std::uint64_t r, std::uint64_t w, std::uint32_t cap) {
  if (w < r) {
    return err("write_index", fmt::format("{} is behind read_index {} (indices only grow)", w, r));
  }
  return err(
      "write_index",
      fmt::format("{} is {} records ahead of read_index {}; the ring holds {}", w, w - r, r, cap));
}

// The format fields: a finished header of this reader's version, as long as the segment.
std::optional<ShmError> format_error(const ShmSegmentHeader& h, std::uint64_t size) {
  // First: a segment whose writer has not finished its header (state is written last, with
  // release) is young, not corrupt, whatever its other fields hold (all zero just after
  // ftruncate). The daemon retries it for a while; rejecting it here lost processes that a
  // scan found between their shm_open and the header's last store.
  if (h.state == static_cast<std::uint32_t>(ShmState::Creating)) {
    return err("state", "still being created");
  }
  if (h.magic != kShmMagic) {
    return err("magic",
               fmt::format("{:#018x} is not a vigil segment's ({:#018x})", h.magic, kShmMagic));
  }
  if (h.abi_version != kShmAbiVersion) {
    return err("abi_version", fmt::format("segment format version {}, this reader "
                                          "reads version {} (different vigil releases)",
                                          h.abi_version, kShmAbiVersion));
  }
  if (h.header_size != sizeof(ShmSegmentHeader)) {
    return err("header_size", fmt::format("{} bytes, version {} has {}", h.header_size,
                                          kShmAbiVersion, sizeof(ShmSegmentHeader)));
  }
  if (h.segment_size != size) {
    return err("segment_size",
               fmt::format("header says {} bytes, the segment has {}{}", h.segment_size, size,
                           size < h.segment_size ? " (truncated)" : ""));
  }
  return std::nullopt;
}

// The message schema: the reader's.
std::optional<ShmError> schema_error(const ShmSegmentHeader& h, const ShmSchema& s) {
  if (h.schema_id != s.id) {
    return err("schema_id", fmt::format("message schema {:#018x} differs from the "
                                        "reader's {:#018x} ({}): built from other "
                                        "message definitions",
                                        h.schema_id, s.id, s.name));
  }
  if (h.type_count != s.type_count) {
    return err("type_count", fmt::format("{} message types, the reader's schema has {}",
                                         h.type_count, s.type_count));
  }
  if (h.payload_size != s.payload_size) {
    return err("payload_size",
               fmt::format("{} bytes, the reader's schema has {}", h.payload_size, s.payload_size));
  }
  return std::nullopt;
}

// The ring's geometry `g`, recomputed from what the reader knows; the header must agree field by
// field, and the segment have its size.
std::optional<ShmError> geometry_error(const ShmSegmentHeader& h, const ShmSchema& s,
                                       std::uint64_t size, ShmGeometry& g) {
  if (h.capacity == 0 || h.capacity > kShmMaxCapacity || (h.capacity & (h.capacity - 1)) != 0) {
    return err("capacity", fmt::format("{} records: must be a power of two in 1..{}", h.capacity,
                                       kShmMaxCapacity));
  }
  g = ShmGeometry::make(s.type_count, s.payload_size, h.capacity);
  if (h.record_size != g.record_size) {
    return err("record_size", fmt::format("{} bytes, expected {}", h.record_size, g.record_size));
  }
  if (h.mailbox_offset != g.mailbox_offset) {
    return err("mailbox_offset",
               fmt::format("{}, expected {}", h.mailbox_offset, g.mailbox_offset));
  }
  if (h.ring_offset != g.ring_offset) {
    return err("ring_offset", fmt::format("{}, expected {}", h.ring_offset, g.ring_offset));
  }
  if (g.segment_size != size) {
    return err("segment_size", fmt::format("{} bytes, a ring of {} records needs {}", size,
                                           h.capacity, g.segment_size));
  }
  return std::nullopt;
}

// Who wrote it (process, supervisor, component, command line), into `info`; the supervisor
// must be `supervisor` unless that is empty.
std::optional<ShmError> read_writer(const ShmSegmentHeader& h, std::string_view supervisor,
                                    ShmSegmentInfo& info) {
  if (h.pid <= 0) return err("pid", fmt::format("{} is not a process id", h.pid));
  info.pid = h.pid;
  info.uid = h.uid;
  info.start_ticks = h.start_ticks;
  info.created_unix_ns = h.created_unix_ns;
  info.component_index = h.component_index;
  auto sup = text(h.supervisor_name, "supervisor_name");
  if (!sup) return sup.error();
  if (!valid_supervisor_name(*sup)) {
    return err("supervisor_name", fmt::format("'{}' is not 1..31 of [A-Za-z0-9_-]", *sup));
  }
  if (!supervisor.empty() && *sup != supervisor) {
    return err("supervisor_name", fmt::format("'{}', expected '{}'", *sup, supervisor));
  }
  info.supervisor_name = std::move(*sup);
  auto comp = text(h.component_name, "component_name");
  if (!comp) return comp.error();
  if (comp->empty()) return err("component_name", "empty");
  info.component_name = std::move(*comp);
  auto proc = text(h.process_name, "process_name");
  if (!proc) return proc.error();
  info.process_name = std::move(*proc);
  auto schema = text(h.schema_name, "schema_name");
  if (!schema) return schema.error();
  info.schema_name = std::move(*schema);
  auto cmd = text(h.command_line, "command_line");
  if (!cmd) return cmd.error();
  info.command_line = std::move(*cmd);
  return std::nullopt;
}

// The state fields and counters: values a writer can have written.
std::optional<ShmError> state_error(const ShmSegmentHeader& h) {
  if (h.state > static_cast<std::uint32_t>(ShmState::Closed)) {
    return err("state", fmt::format("{} is not 0, 1 or 2", h.state));
  }
  if (h.exit_kind > static_cast<std::uint32_t>(ShmExit::Signaled)) {
    return err("exit_kind", fmt::format("{} is not 0, 1 or 2", h.exit_kind));
  }
  if (h.write_index < h.read_index || h.write_index - h.read_index > h.capacity) {
    return indices_error(h.read_index, h.write_index, h.capacity);
  }
  if (h.dropped > h.offered) {
    return err("dropped", fmt::format("{} messages dropped of {} offered", h.dropped, h.offered));
  }
  return std::nullopt;
}

// Every field of the header, in order: what a corruption is named after.
struct FieldSpan {
  std::size_t offset;
  std::size_t size;
  const char* name;
};
constexpr FieldSpan kFields[] = {
    {offsetof(ShmSegmentHeader, magic), sizeof(ShmSegmentHeader::magic), "magic"},
    {offsetof(ShmSegmentHeader, abi_version), sizeof(ShmSegmentHeader::abi_version), "abi_version"},
    {offsetof(ShmSegmentHeader, header_size), sizeof(ShmSegmentHeader::header_size), "header_size"},
    {offsetof(ShmSegmentHeader, segment_size), sizeof(ShmSegmentHeader::segment_size),
     "segment_size"},
    {offsetof(ShmSegmentHeader, schema_id), sizeof(ShmSegmentHeader::schema_id), "schema_id"},
    {offsetof(ShmSegmentHeader, type_count), sizeof(ShmSegmentHeader::type_count), "type_count"},
    {offsetof(ShmSegmentHeader, payload_size), sizeof(ShmSegmentHeader::payload_size),
     "payload_size"},
    {offsetof(ShmSegmentHeader, record_size), sizeof(ShmSegmentHeader::record_size), "record_size"},
    {offsetof(ShmSegmentHeader, capacity), sizeof(ShmSegmentHeader::capacity), "capacity"},
    {offsetof(ShmSegmentHeader, mailbox_offset), sizeof(ShmSegmentHeader::mailbox_offset),
     "mailbox_offset"},
    {offsetof(ShmSegmentHeader, ring_offset), sizeof(ShmSegmentHeader::ring_offset), "ring_offset"},
    {offsetof(ShmSegmentHeader, pid), sizeof(ShmSegmentHeader::pid), "pid"},
    {offsetof(ShmSegmentHeader, uid), sizeof(ShmSegmentHeader::uid), "uid"},
    {offsetof(ShmSegmentHeader, start_ticks), sizeof(ShmSegmentHeader::start_ticks), "start_ticks"},
    {offsetof(ShmSegmentHeader, created_unix_ns), sizeof(ShmSegmentHeader::created_unix_ns),
     "created_unix_ns"},
    {offsetof(ShmSegmentHeader, component_index), sizeof(ShmSegmentHeader::component_index),
     "component_index"},
    {offsetof(ShmSegmentHeader, flags), sizeof(ShmSegmentHeader::flags), "flags"},
    {offsetof(ShmSegmentHeader, supervisor_name), sizeof(ShmSegmentHeader::supervisor_name),
     "supervisor_name"},
    {offsetof(ShmSegmentHeader, component_name), sizeof(ShmSegmentHeader::component_name),
     "component_name"},
    {offsetof(ShmSegmentHeader, process_name), sizeof(ShmSegmentHeader::process_name),
     "process_name"},
    {offsetof(ShmSegmentHeader, schema_name), sizeof(ShmSegmentHeader::schema_name), "schema_name"},
    {offsetof(ShmSegmentHeader, command_line), sizeof(ShmSegmentHeader::command_line),
     "command_line"},
    {offsetof(ShmSegmentHeader, state), sizeof(ShmSegmentHeader::state), "state"},
    {offsetof(ShmSegmentHeader, exit_kind), sizeof(ShmSegmentHeader::exit_kind), "exit_kind"},
    {offsetof(ShmSegmentHeader, exit_code), sizeof(ShmSegmentHeader::exit_code), "exit_code"},
    {offsetof(ShmSegmentHeader, reserved0), sizeof(ShmSegmentHeader::reserved0), "reserved0"},
    {offsetof(ShmSegmentHeader, daemon_heartbeat_ns), sizeof(ShmSegmentHeader::daemon_heartbeat_ns),
     "daemon_heartbeat_ns"},
    {offsetof(ShmSegmentHeader, daemon_pid), sizeof(ShmSegmentHeader::daemon_pid), "daemon_pid"},
    {offsetof(ShmSegmentHeader, reserved1), sizeof(ShmSegmentHeader::reserved1), "reserved1"},
    {offsetof(ShmSegmentHeader, write_index), sizeof(ShmSegmentHeader::write_index), "write_index"},
    {offsetof(ShmSegmentHeader, dropped), sizeof(ShmSegmentHeader::dropped), "dropped"},
    {offsetof(ShmSegmentHeader, offered), sizeof(ShmSegmentHeader::offered), "offered"},
    {offsetof(ShmSegmentHeader, read_index), sizeof(ShmSegmentHeader::read_index), "read_index"},
    {offsetof(ShmSegmentHeader, drains), sizeof(ShmSegmentHeader::drains), "drains"},
    {offsetof(ShmSegmentHeader, header_checksum), sizeof(ShmSegmentHeader::header_checksum),
     "header_checksum"},
    {offsetof(ShmSegmentHeader, reserved2), sizeof(ShmSegmentHeader::reserved2), "reserved2"},
};

// The reserved fields a writer leaves zero: the first one that is not, or null.
const char* reserved_not_zero(const ShmSegmentHeader& h) noexcept {
  if (h.reserved0 != 0) return "reserved0";
  if (h.reserved1 != 0) return "reserved1";
  for (const std::uint8_t b : h.reserved2) {
    if (b != 0) return "reserved2";
  }
  return nullptr;
}

// The integrity fields: the constant part matches its checksum, the reserved fields are zero.
std::optional<ShmError> integrity_error(const ShmSegmentHeader& h) {
  if (const char* f = reserved_not_zero(h)) {
    return err(f, "not zero (reserved: no writer sets it)");
  }
  const std::uint64_t sum = shm_header_checksum(&h);
  if (sum != h.header_checksum) {
    return err("header_checksum",
               fmt::format("{:#018x} does not match the header's constant part ({:#018x}): "
                           "written over since the segment was created",
                           h.header_checksum, sum));
  }
  return std::nullopt;
}

}  // namespace

const char* shm_header_field(std::size_t offset) noexcept {
  for (const FieldSpan& f : kFields) {
    if (offset >= f.offset && offset < f.offset + f.size) return f.name;
  }
  return "header padding";
}

const char* shm_constant_difference(const ShmSegmentHeader& a, const ShmSegmentHeader& b) noexcept {
  const auto* x = reinterpret_cast<const unsigned char*>(&a);
  const auto* y = reinterpret_cast<const unsigned char*>(&b);
  // The usual case first, word-wide (a byte loop over 512 bytes for every segment every 100 ms
  // was about 2 % of the daemon's CPU); the loop only names the field that differs.
  if (std::memcmp(x, y, kShmConstantBytes) == 0) {
    return a.header_checksum != b.header_checksum ? "header_checksum" : nullptr;
  }
  for (std::size_t i = 0; i < kShmConstantBytes; ++i) {
    if (x[i] != y[i]) return shm_header_field(i);
  }
  if (a.header_checksum != b.header_checksum) return "header_checksum";
  return nullptr;
}

bool valid_supervisor_name(std::string_view name) noexcept {
  return !name.empty() && name.size() <= 31 &&
         std::all_of(name.begin(), name.end(), valid_name_char);
}

std::string shm_segment_prefix(std::string_view supervisor) {
  return fmt::format("vigil.{}.", supervisor);
}

std::string shm_segment_name(std::string_view supervisor, std::int32_t pid, std::uint32_t index) {
  return fmt::format("/vigil.{}.{}.{}", supervisor, pid, index);
}

expected<ShmSegmentInfo, ShmError> validate_shm_header(const ShmSegmentHeader& h,
                                                       std::uint64_t size,
                                                       const ShmExpectation& e) {
  ShmSegmentInfo info;
  if (auto x = format_error(h, size)) return unexpected<ShmError>(std::move(*x));
  if (auto x = schema_error(h, e.schema)) return unexpected<ShmError>(std::move(*x));
  if (auto x = geometry_error(h, e.schema, size, info.geometry)) {
    return unexpected<ShmError>(std::move(*x));
  }
  if (auto x = read_writer(h, e.supervisor_name, info)) return unexpected<ShmError>(std::move(*x));
  if (auto x = state_error(h)) return unexpected<ShmError>(std::move(*x));
  // Last: a field whose value is invalid was named above; a plausible value written over the
  // one the writer set is found here.
  if (auto x = integrity_error(h)) return unexpected<ShmError>(std::move(*x));
  return info;
}

expected<ShmSegmentInfo, ShmError> validate_shm_image(const void* bytes, std::size_t size,
                                                      const ShmExpectation& e) {
  if (bytes == nullptr || size < sizeof(ShmSegmentHeader)) {
    return unexpected<ShmError>(err("file", fmt::format("{} bytes, shorter than the {}-byte header "
                                                        "(truncated)",
                                                        size, sizeof(ShmSegmentHeader))));
  }
  ShmSegmentHeader h;
  std::memcpy(&h, bytes, sizeof h);
  return validate_shm_header(h, size, e);
}

expected<void, ShmError> check_shm_file(const platform::ShmFileInfo& f, std::uint32_t uid,
                                        bool allow_group) {
  if (f.uid != uid) {
    return unexpected<ShmError>(
        err("file", fmt::format("owned by uid {}, not by this user (uid {})", f.uid, uid)));
  }
  if ((f.mode & 0007) != 0) {
    return unexpected<ShmError>(
        err("file", fmt::format("mode {:04o} gives access to every user; vigil "
                                "segments are 0600 (or 0660 with a group)",
                                f.mode)));
  }
  if (!allow_group && (f.mode & 0070) != 0) {
    return unexpected<ShmError>(
        err("file", fmt::format("mode {:04o} gives access to group {}; expected "
                                "0600 (name the group to accept it)",
                                f.mode, f.gid)));
  }
  if (f.size > kShmMaxSegmentSize) {
    return unexpected<ShmError>(err(
        "file", fmt::format("{} bytes, more than the {} accepted", f.size, kShmMaxSegmentSize)));
  }
  return {};
}

void init_shm_segment(void* base, const ShmGeometry& g, const ShmSchema& schema,
                      const ShmIdentity& who) noexcept {
  auto* h = static_cast<ShmSegmentHeader*>(base);
  h->magic = kShmMagic;
  h->abi_version = kShmAbiVersion;
  h->header_size = sizeof(ShmSegmentHeader);
  h->segment_size = g.segment_size;
  h->schema_id = schema.id;
  h->type_count = g.type_count;
  h->payload_size = g.payload_size;
  h->record_size = g.record_size;
  h->capacity = g.capacity;
  h->mailbox_offset = g.mailbox_offset;
  h->ring_offset = g.ring_offset;
  h->pid = who.pid;
  h->uid = who.uid;
  h->start_ticks = who.start_ticks;
  h->created_unix_ns = who.created_unix_ns;
  h->component_index = who.component_index;
  h->flags = 0;
  put_text(h->supervisor_name, who.supervisor_name);
  put_text(h->component_name, who.component_name);
  put_text(h->process_name, who.process_name);
  put_text(h->schema_name, schema.name);
  put_text(h->command_line, who.command_line);
  h->header_checksum = shm_header_checksum(h);
  // Last, with release: a reader that sees Open sees every field above.
  at(h->state).store(static_cast<std::uint32_t>(ShmState::Open), std::memory_order_release);
}

// --- ShmRingReader ------------------------------------------------------------------------------

namespace {

struct LiveCtx {
  ShmSegmentHeader* h;
  ShmLiveState out;
};

void read_live(void* p) noexcept {
  auto& c = *static_cast<LiveCtx*>(p);
  ShmSegmentHeader& h = *c.h;
  // State and exit record first: a producer writes its last records before it marks the
  // segment Closed (release), so a reader that sees Closed then sees the final write index.
  c.out.state = static_cast<ShmState>(at(h.state).load(std::memory_order_acquire));
  c.out.exit_kind = static_cast<ShmExit>(at(h.exit_kind).load(std::memory_order_acquire));
  c.out.write_index = at(h.write_index).load(std::memory_order_acquire);
  c.out.exit_code = at(h.exit_code).load(std::memory_order_relaxed);
  c.out.read_index = at(h.read_index).load(std::memory_order_relaxed);
  // `dropped` (acquire) before `offered`, both after `write_index`: the order the bounds
  // checked by live() rely on (ShmProducer::push and drop store them in the opposite order).
  c.out.dropped = at(h.dropped).load(std::memory_order_acquire);
  c.out.offered = at(h.offered).load(std::memory_order_acquire);
  c.out.daemon_heartbeat_ns = at(h.daemon_heartbeat_ns).load(std::memory_order_relaxed);
  c.out.daemon_pid = at(h.daemon_pid).load(std::memory_order_relaxed);
  c.out.drains = at(h.drains).load(std::memory_order_relaxed);
}

ShmError truncated() {
  return err("file", "the segment was truncated while mapped (bus error caught)");
}

}  // namespace

expected<ShmLiveState, ShmError> ShmRingReader::live() const noexcept {
  LiveCtx c{reinterpret_cast<ShmSegmentHeader*>(base_), {}};
  if (!platform::run_guarded(&read_live, &c)) return unexpected<ShmError>(truncated());
  const auto state = static_cast<std::uint32_t>(c.out.state);
  if (state == 0 || state > 2) {
    return unexpected<ShmError>(
        err("state", fmt::format("{} is not 1 or 2 after creation", state)));
  }
  if (static_cast<std::uint32_t>(c.out.exit_kind) > 2) {
    return unexpected<ShmError>(
        err("exit_kind",
            fmt::format("{} is not 0, 1 or 2", static_cast<std::uint32_t>(c.out.exit_kind))));
  }
  if (c.out.write_index < read_ || c.out.write_index - read_ > g_.capacity) {
    return unexpected<ShmError>(indices_error(read_, c.out.write_index, g_.capacity));
  }
  // Only this reader moves the shared read index once it attached.
  if (attached_ && c.out.read_index != read_) {
    return unexpected<ShmError>(
        err("read_index",
            fmt::format("{}, but this reader consumed {} records", c.out.read_index, read_)));
  }
  // The writer publishes a record's write index, then its sequence number in `offered`: the
  // offered number read after the index is at least that of the record before it.
  if (c.out.offered + 1 < c.out.write_index) {
    return unexpected<ShmError>(
        err("offered", fmt::format("{} messages offered, but {} records written", c.out.offered,
                                   c.out.write_index)));
  }
  // A drop counts itself, then its sequence number: at most one drop ahead of `offered`.
  if (c.out.dropped > c.out.offered + 1) {
    return unexpected<ShmError>(err(
        "dropped", fmt::format("{} messages dropped of {} offered", c.out.dropped, c.out.offered)));
  }
  return c.out;
}

namespace {
struct HeaderCopy {
  const std::byte* src;
  ShmSegmentHeader* dst;
};
void copy_header(void* p) noexcept {
  auto& c = *static_cast<HeaderCopy*>(p);
  std::memcpy(c.dst, c.src, sizeof(ShmSegmentHeader));
}
}  // namespace

expected<void, ShmError> ShmRingReader::verify_header(const ShmSegmentHeader& reference,
                                                      ShmSegmentHeader* out) const noexcept {
  ShmSegmentHeader local;
  ShmSegmentHeader& h = out != nullptr ? *out : local;
  HeaderCopy c{base_, &h};
  if (!platform::run_guarded(&copy_header, &c)) return unexpected<ShmError>(truncated());
  // The copy is private: every check below reads the same bytes. A field is named by
  // comparing with the reader's own copy from the open; the checksum stands for the writer's
  // values when the reader has none (a copy taken after a change: see validate_shm_header).
  if (const char* f = shm_constant_difference(h, reference)) {
    return unexpected<ShmError>(
        err(f, std::string(f) == "header_checksum"
                   ? fmt::format("{:#018x}, was {:#018x} (written over)", h.header_checksum,
                                 reference.header_checksum)
                   : std::string("changed after the segment was created (written over; the writer "
                                 "sets it once)")));
  }
  // The constant part and its checksum equal the reference's, whose checksum was verified at
  // open: the checksum holds without being computed again. The reserved fields are not in the
  // constant part: checked here.
  if (const char* f = reserved_not_zero(h)) {
    return unexpected<ShmError>(err(f, "not zero (reserved: no writer sets it)"));
  }
  return {};
}

expected<void, ShmError> ShmRingReader::attach() noexcept {
  LiveCtx c{reinterpret_cast<ShmSegmentHeader*>(base_), {}};
  if (!platform::run_guarded(&read_live, &c)) return unexpected<ShmError>(truncated());
  const std::uint64_t r = c.out.read_index;
  const std::uint64_t w = c.out.write_index;
  if (w < r || w - r > g_.capacity) return unexpected<ShmError>(indices_error(r, w, g_.capacity));
  read_ = r;
  attached_ = true;
  return {};
}

namespace {

struct EachCtx {
  std::byte* base;
  const ShmGeometry* g;
  std::uint64_t read;
  std::size_t max;
  ShmRingReader::RecordFn fn;
  void* ctx;
  std::uint64_t write = 0;
  std::size_t n = 0;
  bool bad = false;
};

void each_record(void* p) noexcept {
  auto& c = *static_cast<EachCtx*>(p);
  auto& h = *reinterpret_cast<ShmSegmentHeader*>(c.base);
  const std::uint64_t w = at(h.write_index).load(std::memory_order_acquire);
  c.write = w;
  if (w < c.read || w - c.read > c.g->capacity) {
    c.bad = true;
    return;
  }
  const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(w - c.read, c.max));
  const std::uint64_t mask = c.g->capacity - 1;
  const std::byte* ring = c.base + c.g->ring_offset;
  const std::size_t rs = c.g->record_size;
  std::size_t i = 0;
  while (i < n && c.fn(c.ctx, ring + ((c.read + i) & mask) * rs)) ++i;
  c.n = i;
  // Release: the producer may reuse the slots once it sees the new index.
  if (i != 0) at(h.read_index).store(c.read + i, std::memory_order_release);
}

}  // namespace

expected<std::size_t, ShmError> ShmRingReader::pop_each(std::size_t max, RecordFn fn,
                                                        void* ctx) noexcept {
  if (max == 0) return std::size_t{0};
  EachCtx c{base_, &g_, read_, max, fn, ctx};
  if (!platform::run_guarded(&each_record, &c)) return unexpected<ShmError>(truncated());
  if (c.bad) return unexpected<ShmError>(indices_error(read_, c.write, g_.capacity));
  read_ += c.n;
  return c.n;
}

namespace {

struct MailCtx {
  std::byte* box;
  std::size_t words;
  std::uint64_t* out;
  bool ok = false;
};

void read_box(void* p) noexcept {
  auto& c = *static_cast<MailCtx*>(p);
  auto* v = reinterpret_cast<std::uint64_t*>(c.box);
  for (int attempt = 0; attempt < 8; ++attempt) {
    const std::uint64_t v1 = at(*v).load(std::memory_order_acquire);
    if ((v1 & 1U) != 0) continue;  // being written
#if defined(__SANITIZE_THREAD__)
    // ThreadSanitizer does not model fences (GCC refuses them): each word's load is an acquire
    // instead, which keeps the version's re-read after it just as the fence does.
    constexpr auto word_order = std::memory_order_acquire;
#else
    constexpr auto word_order = std::memory_order_relaxed;
#endif
    for (std::size_t i = 0; i < c.words; ++i) {
      c.out[i] = at(v[1 + i]).load(word_order);
    }
#if !defined(__SANITIZE_THREAD__)
    std::atomic_thread_fence(std::memory_order_acquire);
#endif
    if (at(*v).load(std::memory_order_relaxed) == v1) {
      c.ok = v1 != 0;
      return;
    }
  }
}

}  // namespace

bool ShmRingReader::read_mailbox(std::uint32_t type, std::byte* out) const noexcept {
  if (type >= g_.type_count) return false;
  alignas(8) std::uint64_t buf[(sizeof(ShmRecordHeader) + kShmMaxPayload) / 8];
  const std::size_t words = g_.record_size / 8;
  if (words > std::size(buf)) return false;
  MailCtx c{base_ + g_.mailbox_offset + g_.mailbox_stride * type, words, buf};
  if (!platform::run_guarded(&read_box, &c) || !c.ok) return false;
  std::memcpy(out, buf, g_.record_size);
  return true;
}

namespace {
struct BeatCtx {
  ShmSegmentHeader* h;
  std::int64_t now;
  std::int32_t pid;
};
void beat(void* p) noexcept {
  auto& c = *static_cast<BeatCtx*>(p);
  at(c.h->daemon_pid).store(c.pid, std::memory_order_relaxed);
  at(c.h->daemon_heartbeat_ns).store(c.now, std::memory_order_relaxed);
  at(c.h->drains).fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

void ShmRingReader::heartbeat(std::int64_t now, std::int32_t pid) noexcept {
  BeatCtx c{reinterpret_cast<ShmSegmentHeader*>(base_), now, pid};
  (void)platform::run_guarded(&beat, &c);
}

}  // namespace vigil::bus
