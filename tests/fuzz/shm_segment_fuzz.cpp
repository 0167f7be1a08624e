// Fuzz target: a shared-memory port segment as another process could leave it (truncated,
// corrupted, hostile), read the way `vigil supervise` reads it. The first byte chooses how the
// rest is used:
//  - even: the rest is a whole segment image. (1) In anonymous memory: header validation
//    (validate_shm_image), then the ring (indices, records) and the mailboxes, each record
//    decoded and checked (check_shm_message) and aggregated. (2) As a real segment
//    (/dev/shm/vigil.<name>.<pid>.0, owner-only, like a process's) read by the daemon itself:
//    service::SegmentSource::step() (discovery, file and header checks, attach, sticky
//    mailboxes, drain, settle, end of a dead process) and a monitor cycle on what it aggregated.
//    Placeholders keep the daemon's path reachable from a fixed image: a supervisor name "fuzz"
//    stands for this process's daemon name, and pid 4242 with start ticks 123 for this process
//    (so the writer is alive); anything else is read as it is.
//  - odd: the rest is a sequence of messages in a valid segment of this process: each one is a
//    byte k (type: k's low 7 bits mod the types; bit 7: in the type's mailbox instead of the
//    ring) and the type's payload bytes; bit 1 of the first byte closes the segment (the component
//    left). This reaches the message checks and everything downstream (aggregator, monitor) at
//    once.
// Whatever the bytes: no crash, no read outside the segment, no undefined behaviour downstream,
// and every rejection names a field and says why.
#include <sys/mman.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/platform/shm.hpp"
#include "vigil/service/supervision_service.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/shm_messages.hpp"

namespace {

using namespace vigil;

void check(bool ok) {
  if (!ok) __builtin_trap();
}

constexpr std::int32_t kSelfPidPlaceholder = 4242;
constexpr std::uint64_t kSelfTicksPlaceholder = 123;
constexpr char kSupervisorPlaceholder[] = "fuzz";

struct Self {
  std::int32_t pid = platform::current_pid();
  std::uint64_t ticks = platform::process_start_ticks(pid).value_or(0);
  std::uint32_t uid = platform::effective_uid();
  // Per process: fuzzers running side by side (CI, a campaign, CTest) never see each other's
  // segments.
  std::string supervisor = "fuzz-" + std::to_string(pid);
  std::string segment = bus::shm_segment_name(supervisor, pid, 0);
};

const Self& self() {
  static const Self s;
  return s;
}

class NoPort final : public PortReader<task::Message> {
 public:
  std::size_t pop(task::Message* /*out*/, std::size_t /*max*/) noexcept override { return 0; }
  [[nodiscard]] std::size_t read_available() const noexcept override { return 0; }
  [[nodiscard]] std::size_t capacity() const noexcept override { return 1; }
};

// (1) The image in anonymous memory, read with the reader's primitives.
void read_image(const std::uint8_t* data, std::size_t size) {
  const std::size_t mapped = std::max<std::size_t>(size, 1);
  void* p = ::mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return;
  std::unique_ptr<void, std::function<void(void*)>> unmap(
      p, [mapped](void* q) { ::munmap(q, mapped); });
  auto* image = static_cast<std::byte*>(p);
  if (size > 0) std::memcpy(image, data, size);

  const bus::ShmExpectation expect{task::kShmMessageSchema, kSupervisorPlaceholder};
  auto info = bus::validate_shm_image(image, size, expect);
  if (!info) {
    check(!info.error().field.empty() && !info.error().message.empty());
    return;
  }
  const bus::ShmGeometry& g = info->geometry;
  check(g.segment_size == size);
  check(g.ring_offset + std::uint64_t{g.capacity} * g.record_size <= size);

  supervisor::ComponentAggregator aggregator;
  bus::RegistryEntry<task::Message> entry;
  entry.id = 1;
  entry.name = info->component_name;
  entry.port = std::make_shared<NoPort>();
  aggregator.on_join(entry);
  const auto feed = [&](task::Message& m) {
    std::string why;
    if (!task::check_shm_message(m, why)) {
      check(!why.empty());
      return;
    }
    aggregator.begin(entry);
    std::visit([&](const auto& x) { aggregator.on(entry, x); }, m);
    aggregator.end(entry, supervisor::PortDrain{});
  };

  bus::ShmRingReader reader(image, g);
  if (auto a = reader.attach(); !a) {
    check(!a.error().message.empty());
    return;
  }
  std::vector<std::byte> raw(static_cast<std::size_t>(g.record_size) * g.capacity);
  struct Copy {
    std::byte* out;
    std::size_t size;
    std::size_t n = 0;
  } copy{raw.data(), g.record_size};
  // Every record in place, copied out as they are (the daemon decodes them in place instead).
  auto n = reader.pop_each(
      g.capacity,
      [](void* ctx, const std::byte* rec) noexcept {
        auto& c = *static_cast<Copy*>(ctx);
        std::memcpy(c.out + c.n++ * c.size, rec, c.size);
        return true;
      },
      &copy);
  if (n) {
    check(*n <= g.capacity);
    for (std::size_t i = 0; i < *n; ++i) {
      task::Message m;
      bus::ShmError why;
      if (bus::decode_shm_record(raw.data() + i * g.record_size, m, &why)) {
        feed(m);
      } else {
        check(!why.message.empty());
      }
    }
  }
  std::vector<std::byte> rec(g.record_size);
  for (std::uint32_t t = 0; t < g.type_count + 1; ++t) {
    if (!reader.read_mailbox(t, rec.data())) continue;
    task::Message m;
    if (bus::decode_shm_record(rec.data(), m, nullptr)) feed(m);
  }
  (void)reader.live();
  for (const auto& s : aggregator.snapshot()) check(s.name == info->component_name);
}

// Replaces the placeholders (see the top of the file) in a header at `image`.
void substitute(std::byte* image, std::size_t size) {
  if (size < sizeof(bus::ShmSegmentHeader)) return;
  bus::ShmSegmentHeader h;
  std::memcpy(&h, image, sizeof h);
  // A header whose checksum held keeps it after the substitution (otherwise every seed would
  // stop at header_checksum).
  const bool summed = bus::shm_header_checksum(&h) == h.header_checksum;
  if (std::memcmp(h.supervisor_name, kSupervisorPlaceholder, sizeof kSupervisorPlaceholder) == 0) {
    std::memset(h.supervisor_name, 0, sizeof h.supervisor_name);
    std::memcpy(h.supervisor_name, self().supervisor.data(), self().supervisor.size());
  }
  if (h.pid == kSelfPidPlaceholder && h.start_ticks == kSelfTicksPlaceholder) {
    h.pid = self().pid;
    h.start_ticks = self().ticks;
    h.uid = self().uid;
  }
  if (summed) h.header_checksum = bus::shm_header_checksum(&h);
  std::memcpy(image, &h, sizeof h);
}

// (2) The bytes as this process's segment, read by the daemon.
void supervise(const std::byte* image, std::size_t size) {
  const Self& me = self();
  (void)platform::unlink_shared_memory(me.segment);
  if (size == 0) return;
  auto mem = platform::SharedMemory::create(me.segment, size);
  if (!mem) return;
  std::memcpy(mem->data(), image, size);
  substitute(static_cast<std::byte*>(mem->data()), size);

  service::SupervisionServiceOptions o;
  // No inotify instance per input (closing one sleeps in the kernel for milliseconds: the
  // fuzzer spent ~90 % of its time there); a full listing at every step instead.
  o.segments = service::SegmentSourceOptions{
      .name = me.supervisor, .rescan_ns = 0, .watch_directory = false};
  o.summary_file = nullptr;
  check(service::validate(*o.segments).has_value());
  auto daemon = std::make_unique<service::SupervisionService>(std::move(o));
  (void)daemon->segments()->step();
  const ReportSet reports = daemon->step();  // a second drain, then a monitor cycle
  const std::vector<Event> events = daemon->events().since(0);
  for (const Report& r : reports.components) (void)r.name.size();
  static const bool verbose = std::getenv("VIGIL_FUZZ_VERBOSE") != nullptr;
  if (verbose) {
    for (const Report& r : reports.components) {
      std::fprintf(stderr, "  report %s: %s, %llu cycles\n", r.name.c_str(),
                   to_string(r.status.level()), static_cast<unsigned long long>(r.counters.cycles));
    }
  }
  for (const Event& e : events) {
    if (verbose) std::fprintf(stderr, "  event: %s\n", format_event(e).c_str());
    if (e.kind == EventKind::SegmentRejected) {
      // "segment /vigil... rejected: <field>: <why>"
      check(e.detail.find("rejected: ") != std::string::npos);
    }
    if (e.kind == EventKind::Joined || e.kind == EventKind::Left ||
        e.kind == EventKind::ProcessExited) {
      check(!e.detail.empty());
    }
  }
  daemon.reset();
  (void)platform::unlink_shared_memory(me.segment);
}

// The messages of a valid segment of this process (see the top of the file).
std::vector<std::byte> message_image(std::uint8_t mode, const std::uint8_t* data,
                                     std::size_t size) {
  const Self& me = self();
  const bus::ShmGeometry g = bus::ShmGeometry::make(task::kShmMessageSchema.type_count,
                                                    task::kShmMessageSchema.payload_size, 8);
  std::vector<std::byte> image(g.segment_size);
  bus::ShmIdentity who;
  who.supervisor_name = me.supervisor;
  who.component_name = "fuzzed";
  who.pid = me.pid;
  who.uid = me.uid;
  who.start_ticks = me.ticks;
  who.process_name = "fuzz";
  who.command_line = "fuzz --messages";
  bus::init_shm_segment(image.data(), g, task::kShmMessageSchema, who);
  constexpr auto sizes = bus::detail::VariantTypes<task::Message>::sizes;
  std::uint64_t seq = 0;
  std::uint64_t write = 0;
  std::size_t at = 0;
  while (at < size) {
    const std::uint8_t k = data[at++];
    const std::uint32_t type = (k & 0x7FU) % task::kShmMessageSchema.type_count;
    const bool mailbox = (k & 0x80U) != 0 || write == g.capacity;
    std::byte* rec = mailbox ? image.data() + g.mailbox_offset + type * g.mailbox_stride + 8
                             : image.data() + g.ring_offset + write * g.record_size;
    const bus::ShmRecordHeader h{++seq, type, sizes[type]};
    std::memcpy(rec, &h, sizeof h);
    const std::size_t n = std::min<std::size_t>(sizes[type], size - at);
    std::memcpy(rec + sizeof h, data + at, n);
    at += n;
    if (mailbox) {
      const std::uint64_t version = 2;  // even: written
      std::memcpy(rec - 8, &version, sizeof version);
    } else {
      ++write;
    }
  }
  bus::ShmSegmentHeader header;
  std::memcpy(&header, image.data(), sizeof header);
  header.write_index = write;
  header.offered = seq;
  header.dropped = seq - write;
  if ((mode & 2U) != 0) header.state = static_cast<std::uint32_t>(bus::ShmState::Closed);
  std::memcpy(image.data(), &header, sizeof header);
  return image;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > (1U << 20)) return 0;
  const std::uint8_t mode = data[0];
  ++data;
  --size;
  if ((mode & 1U) == 0) {
    read_image(data, size);
    std::vector<std::byte> copy(size);
    if (size > 0) std::memcpy(copy.data(), data, size);
    supervise(copy.data(), copy.size());
  } else {
    const std::vector<std::byte> image = message_image(mode, data, size);
    supervise(image.data(), image.size());
  }
  return 0;
}
