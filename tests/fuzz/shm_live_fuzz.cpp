// Fuzz target: a live segment written over while its writer pushes into it and the daemon reads
// it (issue 49 item 1). Each input is a script run against one fresh segment of this process
// (a real /dev/shm segment, created by ShmSession, pushed into by the real ShmProducer) and one
// `vigil supervise` pipeline (SupervisionService on a SegmentSource, stepped by hand). Byte by
// byte, an operation (low 3 bits) and its arguments:
//   0 push n (1..8) cycle samples (the writer's real-time push; a full ring drops into the
//     mailbox, as the port does)
//   1 write over the segment: a 16-bit offset (mod the segment size), a length (1..16), bytes
//     (a wild pointer in the writer's process)
//   2 a daemon drain
//   3 a monitor cycle (a report: the headers are verified again)
//   4 push a sticky message (a state change) or keep one for a retry
//   5 flip one bit: a 16-bit bit index within the header (the fields the writer set once)
//   6 close the segment (the component leaves)
//   7 wait: the header check falls due at the next drain (its period is 0 here)
// The script is deterministic (one thread interleaves the writer, the damage and the daemon), so
// a finding replays exactly. Whatever the bytes: no crash, no read outside the segment; once the
// daemon says the segment is corrupted it never reads it again (the component's counters do not
// move any more) and its report is ERROR naming the field; every event about it names a field.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/bus/shm_session.hpp"
#include "vigil/platform/process_watch.hpp"
#include "vigil/platform/shm.hpp"
#include "vigil/service/supervision_service.hpp"
#include "vigil/task/shm_messages.hpp"

namespace {

using namespace vigil;

void check(bool ok) {
  if (!ok) __builtin_trap();
}

const std::string& live_supervisor() {
  static const std::string s = "fuzzlive-" + std::to_string(platform::current_pid());
  return s;
}

task::Message sample(std::uint64_t cycle) {
  task::CycleSample s;
  s.release_ns = static_cast<Nanos>(cycle) * kNanosPerMilli;
  s.start_ns = s.release_ns + 10;
  s.end_ns = s.start_ns + 1000;
  s.state = TaskState::Running;
  s.counters.cycles = cycle;
  return task::Message{s};
}

struct Script {
  const std::uint8_t* data;
  std::size_t size;
  std::size_t at = 0;
  [[nodiscard]] bool more() const { return at < size; }
  std::uint8_t byte() { return at < size ? data[at++] : 0; }
  std::uint16_t word() {
    const std::uint16_t lo = byte();
    return static_cast<std::uint16_t>(lo | (byte() << 8U));
  }
};

// The component "live" as the daemon reports it (null when it is not in the set).
const Report* report_of(const ReportSet& set) {
  for (const Report& r : set.components) {
    if (r.name == "live") return &r;
  }
  return nullptr;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;
  const std::string& sup = live_supervisor();
  auto session = bus::ShmSession::open(bus::ShmOptions{sup, "", 0, {}}, task::kShmMessageSchema);
  check(session.has_value());
  auto segment = (*session)->create("live", 16);
  if (!segment) return 0;  // /dev/shm full: nothing to fuzz
  bus::ShmSegment& seg = **segment;
  bus::ShmProducer<task::Message> producer(seg.data(), seg.geometry(), task::kShmStickyMessages);
  auto* base = static_cast<std::byte*>(seg.data());
  const std::size_t seg_size = seg.geometry().segment_size;

  service::SupervisionServiceOptions o;
  o.segments = service::SegmentSourceOptions{.name = sup,
                                             .rescan_ns = 0,
                                             .watch_directory = false,
                                             .state_check_ns = 0,
                                             .header_check_ns = 0};
  o.summary_file = nullptr;
  check(service::validate(*o.segments).has_value());
  auto daemon = std::make_unique<service::SupervisionService>(std::move(o));

  std::uint64_t cycle = 0;
  std::uint64_t dropped = 0;
  bool corrupted = false;
  std::uint64_t cycles_at_corruption = 0;
  const auto after_drain = [&] {
    if (corrupted) {
      // Never read again: what the aggregator holds of it does not move.
      const auto s = daemon->aggregator().find("live");
      if (s) check(s->counters.cycles == cycles_at_corruption);
      return;
    }
    if (daemon->segments()->stats().corrupted > 0) {
      corrupted = true;
      const auto s = daemon->aggregator().find("live");
      cycles_at_corruption = s ? s->counters.cycles : 0;
    }
  };
  Script in{data, size};
  int ops = 0;
  while (in.more() && ops++ < 512) {
    const std::uint8_t op = in.byte();
    switch (op & 7U) {
      case 0: {
        const unsigned n = 1U + ((op >> 3U) & 7U);
        for (unsigned i = 0; i < n; ++i) {
          const task::Message m = sample(++cycle);
          if (!producer.push(m)) producer.drop(m, ++dropped);
        }
        break;
      }
      case 1: {
        const std::size_t offset = in.word() % seg_size;
        const std::size_t len = std::min<std::size_t>(1 + (in.byte() & 15U), seg_size - offset);
        for (std::size_t i = 0; i < len; ++i) base[offset + i] = std::byte{in.byte()};
        break;
      }
      case 2:
        (void)daemon->segments()->step();
        after_drain();
        break;
      case 3: {
        const ReportSet set = daemon->step();  // a drain, then a monitor cycle
        after_drain();
        if (corrupted) {
          if (const Report* r = report_of(set)) {
            check(r->status.level() == StatusLevel::Error);
          }
        }
        break;
      }
      case 4: {
        task::StateChange c;
        c.from = TaskState::Stopped;
        c.to = TaskState::Running;
        const task::Message m{c};
        if ((op & 8U) != 0) {
          producer.keep(m);
        } else if (!producer.push(m)) {
          producer.drop(m, ++dropped);
        }
        break;
      }
      case 5: {
        const std::size_t bit = in.word() % (bus::kShmConstantBytes * 8);
        base[bit / 8] ^= std::byte{static_cast<unsigned char>(1U << (bit % 8))};
        break;
      }
      case 6:
        producer.close();
        break;
      default:
        break;
    }
  }
  (void)daemon->step();
  after_drain();
  for (const Event& e : daemon->events().since(0)) {
    if (e.kind == EventKind::SegmentCorrupted) {
      // "segment /vigil... of component live (process N) corrupted: <field>: <why>; ..."
      check(e.detail.find("corrupted: ") != std::string::npos);
      check(e.severity == EventSeverity::Error);
    }
    if (e.kind == EventKind::SegmentRejected)
      check(e.detail.find("rejected: ") != std::string::npos);
  }
  static const bool verbose = std::getenv("VIGIL_FUZZ_VERBOSE") != nullptr;
  if (verbose) {
    for (const Event& e : daemon->events().since(0)) {
      std::fprintf(stderr, "  event: %s\n", format_event(e).c_str());
    }
  }
  daemon.reset();
  segment->reset();
  (void)platform::unlink_shared_memory(bus::shm_segment_name(sup, platform::current_pid(), 0));
  return 0;
}
