// Corruption of live segments (issue 49 item 1) and a daemon killed and restarted (item 4), end to
// end: forked children whose components push at 1 kHz into shared memory, the `vigil supervise`
// pipeline in the test process (stepped by hand), and the test writing over the segments.
//
// Corruption: one component per header field (and per kind of record damage); the test writes
// over that field of that component's segment while its child pushes, and checks that the daemon
// names the field, raises a `segment_corrupted` event, reports the component ERROR "segment
// corrupted: <field>" with the counters it had, never reads the segment again, and that the
// other components stay OK. A field the writer rewrites with every push (write_index, offered)
// can be healed by the writer before the daemon looks: that did no harm, and the test writes it
// over again until the daemon saw it.
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>
#include <csignal>

#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstddef>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "../bus/shm_support.hpp"
#include "children.hpp"
#include "support/segment_daemon.hpp"
#include "vigil/bus/shm_port.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/platform/shm.hpp"
#include "vigil/task/shm_messages.hpp"
#include "vigil/task/task.hpp"

using namespace vigil;
using namespace std::chrono_literals;
using vigil::test::ChildLink;
using vigil::test::Ctl;
using vigil::test::spawn;

namespace {

// What the test damages, and the field the daemon must name.
struct Damage {
  std::string expect;         // the field named in the error
  std::size_t offset = 0;     // header offset written over (for header damage)
  std::size_t size = 0;       // bytes written over (0: a record is damaged instead)
  int record = 0;             // 1: the pending record's seq, 2: its type, 3: its size, 4: payload
  bool writer_heals = false;  // the writer rewrites the field: write it over until seen
};

#define VIGIL_FIELD(f) \
  Damage { #f, offsetof(bus::ShmSegmentHeader, f), sizeof(bus::ShmSegmentHeader::f) }

std::vector<Damage> damages() {
  std::vector<Damage> d = {
      VIGIL_FIELD(magic),
      VIGIL_FIELD(abi_version),
      VIGIL_FIELD(header_size),
      VIGIL_FIELD(segment_size),
      VIGIL_FIELD(schema_id),
      VIGIL_FIELD(type_count),
      VIGIL_FIELD(payload_size),
      VIGIL_FIELD(record_size),
      VIGIL_FIELD(capacity),
      VIGIL_FIELD(mailbox_offset),
      VIGIL_FIELD(ring_offset),
      VIGIL_FIELD(pid),
      VIGIL_FIELD(uid),
      VIGIL_FIELD(start_ticks),
      VIGIL_FIELD(created_unix_ns),
      VIGIL_FIELD(component_index),
      VIGIL_FIELD(flags),
      VIGIL_FIELD(supervisor_name),
      VIGIL_FIELD(component_name),
      VIGIL_FIELD(process_name),
      VIGIL_FIELD(schema_name),
      VIGIL_FIELD(command_line),
      VIGIL_FIELD(state),
      VIGIL_FIELD(exit_kind),
      VIGIL_FIELD(exit_code),
      VIGIL_FIELD(reserved0),
      VIGIL_FIELD(daemon_heartbeat_ns),
      VIGIL_FIELD(daemon_pid),
      VIGIL_FIELD(reserved1),
      VIGIL_FIELD(write_index),
      VIGIL_FIELD(dropped),
      VIGIL_FIELD(offered),
      VIGIL_FIELD(read_index),
      VIGIL_FIELD(drains),
      VIGIL_FIELD(header_checksum),
      VIGIL_FIELD(reserved2),
  };
  for (auto& x : d) x.writer_heals = x.expect == "write_index" || x.expect == "offered";
  d.push_back(Damage{"record.seq", 0, 0, 1});
  d.push_back(Damage{"record.type", 0, 0, 2});
  d.push_back(Damage{"record.size", 0, 0, 3});
  d.push_back(Damage{"record", 0, 0, 4});
  return d;
}
#undef VIGIL_FIELD

// Child body: one component per name at 1 kHz, each on its own periodic thread.
void run_many(const ChildLink& link, const std::string& sup, std::size_t count) {
  Registry<task::Message> reg;
  bus::ShmOptions o;
  o.name = sup;
  if (!place_in_shared_memory(reg, o)) ::_exit(90);
  std::vector<std::unique_ptr<Ctl>> tasks;
  std::vector<std::unique_ptr<PeriodicActivity>> acts;
  for (std::size_t i = 0; i < count; ++i) {
    tasks.push_back(std::make_unique<Ctl>("c" + std::to_string(i), reg));
    tasks.back()->configure();
    acts.push_back(std::make_unique<PeriodicActivity>(
        *tasks.back(), PeriodicConfig{.name = "c", .period_ns = kNanosPerMilli}));
    if (!acts.back()->start()) ::_exit(91);
  }
  for (auto& t : tasks) {
    while (t->cycles() < 20) std::this_thread::sleep_for(1ms);
  }
  link.ready();
  for (;;) ::pause();
}

std::vector<Event> events_of(test::Daemon& d, std::vector<Event>& all, EventKind k) {
  auto more = d.take_events();
  all.insert(all.end(), more.begin(), more.end());
  std::vector<Event> out;
  std::copy_if(all.begin(), all.end(), std::back_inserter(out),
               [&](const Event& e) { return e.kind == k; });
  return out;
}

const Report* find_report(const ReportSet& set, const std::string& name) {
  for (const Report& r : set.components) {
    if (r.name == name) return &r;
  }
  return nullptr;
}

}  // namespace

TEST_CASE("Every header field and record of a live segment, written over, is found and named",
          "[integration][multi_process][corruption]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  const std::vector<Damage> all = damages();
  // One spare component that nobody damages: it must stay OK throughout.
  const std::size_t n = all.size() + 1;
  auto child = spawn([&](const ChildLink& l) { run_many(l, name, n); });
  REQUIRE(child->wait_ready(30s));
  test::DaemonOptions o;
  o.name = name;
  o.monitor.read_thread_stats = false;
  o.header_check_ns = 5 * kNanosPerMilli;
  auto made = test::Daemon::create(o);
  REQUIRE(made.has_value());
  test::Daemon& d = **made;
  std::vector<Event> events;
  const auto joined_by = std::chrono::steady_clock::now() + 20s;
  while (events_of(d, events, EventKind::Joined).size() < n &&
         std::chrono::steady_clock::now() < joined_by) {
    d.step();
    std::this_thread::sleep_for(2ms);
  }
  REQUIRE(events_of(d, events, EventKind::Joined).size() == n);
  const pid_t pid = child->pid;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const Damage& dmg = all[i];
    const std::string component = "c" + std::to_string(i);
    INFO("damage to " << dmg.expect << " of " << component);
    // The segment of component i is vigil.<name>.<pid>.<i> (index = join order).
    auto mem = platform::SharedMemory::open(bus::shm_segment_name(name, pid, std::uint32_t(i)),
                                            bus::kShmMaxSegmentSize);
    REQUIRE(mem.has_value());
    auto* base = static_cast<std::byte*>(mem->data());
    auto* h = reinterpret_cast<bus::ShmSegmentHeader*>(base);
    d.step();
    const auto before = d.aggregator().find(component);
    REQUIRE(before.has_value());
    const std::uint64_t cycles_before = before->counters.cycles;
    REQUIRE(cycles_before > 0);
    std::vector<std::byte> garbage;
    bool found = false;
    for (int attempt = 0; attempt < 200 && !found; ++attempt) {
      if (dmg.size > 0) {
        if (garbage.empty()) {  // the field's bytes, every bit flipped, once: then the same
          garbage.assign(base + dmg.offset, base + dmg.offset + dmg.size);
          for (auto& b : garbage) b ^= std::byte{0xA5};
        }
        std::memcpy(base + dmg.offset, garbage.data(), dmg.size);
      } else {
        // A record the daemon has not read yet: wait until the writer pushed one.
        std::this_thread::sleep_for(4ms);
        const std::uint64_t r = std::atomic_ref<std::uint64_t>(h->read_index).load();
        const std::uint64_t w = std::atomic_ref<std::uint64_t>(h->write_index).load();
        if (w <= r) continue;
        std::byte* rec = base + h->ring_offset + (r % h->capacity) * h->record_size;
        bus::ShmRecordHeader rh;
        std::memcpy(&rh, rec, sizeof rh);
        if (dmg.record == 1) rh.seq = 0;
        if (dmg.record == 2) rh.type = 0xA5A5A5A5;
        if (dmg.record == 3) rh.size ^= 0x40;
        if (dmg.record == 4) {
          if (rh.type != 1) continue;  // a CycleSample: its `overrun` bool becomes 7
          rec[sizeof rh + offsetof(task::CycleSample, overrun)] = std::byte{7};
        }
        std::memcpy(rec, &rh, sizeof rh);
      }
      d.step();
      std::this_thread::sleep_for(6ms);  // the writer pushes; the header check falls due
      d.step();
      const ReportSet set = d.reports();  // verifies every header too
      d.step();
      for (const Event& e : events_of(d, events, EventKind::SegmentCorrupted)) {
        if (e.component == component) {
          found = true;
          CHECK(e.severity == EventSeverity::Error);
          CHECK(e.pid == pid);
          CHECK_THAT(e.detail, Catch::Contains("corrupted: " + dmg.expect + ":"));
        }
      }
      (void)set;
    }
    REQUIRE(found);
    // The component: ERROR, named cause, counters as they were (never below what was counted).
    const ReportSet set = d.reports();
    const Report* r = find_report(set, component);
    REQUIRE(r != nullptr);
    CHECK(r->status.level() == StatusLevel::Error);
    CHECK_THAT(r->status.summary(), Catch::Contains("segment corrupted: " + dmg.expect + " ("));
    CHECK(r->state_label == "segment corrupted");
    CHECK(r->counters.cycles >= cycles_before);
    // Never read again: its counters no longer move while the writer goes on.
    std::this_thread::sleep_for(20ms);
    d.step();
    const ReportSet later = d.reports();
    const Report* r2 = find_report(later, component);
    REQUIRE(r2 != nullptr);
    CHECK(r2->counters.cycles == r->counters.cycles);
    CHECK(r2->status.level() == StatusLevel::Error);
  }
  // The untouched component is still read and OK; the process is alive and running.
  const std::string spare = "c" + std::to_string(all.size());
  const auto s1 = d.aggregator().find(spare);
  REQUIRE(s1.has_value());
  std::this_thread::sleep_for(20ms);
  d.step();
  const auto s2 = d.aggregator().find(spare);
  REQUIRE(s2.has_value());
  CHECK(s2->counters.cycles > s1->counters.cycles);
  const ReportSet set = d.reports();
  const Report* spare_report = find_report(set, spare);
  REQUIRE(spare_report != nullptr);
  INFO("the spare component's report: " << spare_report->status.summary());
  CHECK(spare_report->status.level() != StatusLevel::Error);
  CHECK(d.stats().corrupted == all.size());
  CHECK(events_of(d, events, EventKind::SegmentCorrupted).size() == all.size());
  CHECK(events_of(d, events, EventKind::ProcessExited).empty());
  // Its end: the corrupted segments' files are removed with the others.
  child->kill_and_reap(SIGKILL);
  const auto end_by = std::chrono::steady_clock::now() + 10s;
  while (cleanup.count() > 0 && std::chrono::steady_clock::now() < end_by) {
    d.step();
    std::this_thread::sleep_for(2ms);
  }
  CHECK(cleanup.count() == 0);
}

namespace {

// Child body for the restart test: one component at 1 kHz; on "go" it stops it and sends the
// number of cycles it ran (8 bytes), as it counted them itself.
void run_counted(const ChildLink& link, const std::string& sup, const std::string& component) {
  Registry<task::Message> reg;
  bus::ShmOptions o;
  o.name = sup;
  if (!place_in_shared_memory(reg, o)) ::_exit(90);
  Ctl t(component, reg);
  t.configure();
  PeriodicActivity act(t, PeriodicConfig{.name = "c", .period_ns = kNanosPerMilli});
  if (!act.start()) ::_exit(91);
  while (t.cycles() < 20) std::this_thread::sleep_for(1ms);
  link.ready();
  link.wait_go();
  act.stop();
  const std::uint64_t cycles = t.cycles();
  if (::write(link.to_parent, &cycles, sizeof cycles) != sizeof cycles) ::_exit(92);
  for (;;) ::pause();
}

// Child body of the first daemon: drains (its own thread) until it is killed; says ready once it
// drained `segments` segments.
void run_daemon(const ChildLink& link, const std::string& sup, std::size_t segments) {
  test::DaemonOptions o;
  o.name = sup;
  o.monitor.read_thread_stats = false;
  auto d = test::Daemon::create(o);
  if (!d || !(*d)->start()) ::_exit(93);
  while ((*d)->stats().segments < segments || (*d)->stats().cycles < 20) {
    std::this_thread::sleep_for(5ms);
  }
  link.ready();
  for (;;) ::pause();
}

std::optional<std::uint64_t> read_count(const test::Child& c, std::chrono::milliseconds timeout) {
  pollfd p{c.from_child, POLLIN, 0};
  if (::poll(&p, 1, static_cast<int>(timeout.count())) != 1) return std::nullopt;
  std::uint64_t v = 0;
  if (::read(c.from_child, &v, sizeof v) != sizeof v) return std::nullopt;
  return v;
}

}  // namespace

TEST_CASE("A daemon killed with SIGKILL and started again: every total continues exact",
          "[integration][multi_process][restart]") {
  const std::string name = test::unique_supervisor_name();
  test::ShmCleanup cleanup(name);
  constexpr std::size_t kProcesses = 20;
  std::vector<std::unique_ptr<test::Child>> children;
  for (std::size_t i = 0; i < kProcesses; ++i) {
    const std::string component = "p" + std::to_string(i);
    children.push_back(spawn([&](const ChildLink& l) { run_counted(l, name, component); }));
  }
  for (auto& c : children) REQUIRE(c->wait_ready(30s));
  // The first daemon, in a process of its own (this process has no thread yet: fork is safe).
  auto first = spawn([&](const ChildLink& l) { run_daemon(l, name, kProcesses); });
  REQUIRE(first->wait_ready(30s));
  std::this_thread::sleep_for(100ms);
  const pid_t first_pid = first->pid;
  first->kill_and_reap(SIGKILL);
  // Down long enough for the rings to fill: the newest messages are dropped meanwhile.
  std::this_thread::sleep_for(600ms);
  test::DaemonOptions o;
  o.name = name;
  o.monitor.read_thread_stats = false;
  auto made = test::Daemon::create(o);
  REQUIRE(made.has_value());
  test::Daemon& d = **made;
  std::vector<Event> events;
  const auto joined_by = std::chrono::steady_clock::now() + 20s;
  while (events_of(d, events, EventKind::Joined).size() < kProcesses &&
         std::chrono::steady_clock::now() < joined_by) {
    d.step();
    std::this_thread::sleep_for(2ms);
  }
  REQUIRE(events_of(d, events, EventKind::Joined).size() == kProcesses);
  // The outage is the daemon's own, named once with the killed daemon's pid.
  const auto restarted = events_of(d, events, EventKind::SupervisorRestarted);
  REQUIRE(restarted.size() == 1);
  CHECK(restarted[0].pid == first_pid);
  CHECK(restarted[0].severity == EventSeverity::Warn);
  CHECK_THAT(restarted[0].detail, Catch::Contains("the daemon was down from"));
  CHECK_THAT(restarted[0].detail,
             Catch::Contains("daemon " + std::to_string(first_pid) + " stopped draining"));
  CHECK_THAT(restarted[0].detail, Catch::Contains("20 segments of 20 processes"));
  CHECK(d.stats().adopted == kProcesses);
  // The components' totals continue: already past what they had at the kill.
  for (std::size_t i = 0; i < kProcesses; ++i) {
    const auto s = d.aggregator().find("p" + std::to_string(i));
    REQUIRE(s.has_value());
    CHECK(s->counters.cycles > 100);
  }
  // Let them run under the new daemon, then stop each and compare with its own count.
  for (int k = 0; k < 50; ++k) {
    d.step();
    std::this_thread::sleep_for(10ms);
  }
  std::vector<std::uint64_t> counted(kProcesses, 0);
  for (std::size_t i = 0; i < kProcesses; ++i) {
    children[i]->go();
    const auto v = read_count(*children[i], 10s);
    REQUIRE(v.has_value());
    counted[i] = *v;
  }
  const auto exact = [&] {
    for (std::size_t i = 0; i < kProcesses; ++i) {
      const auto s = d.aggregator().find("p" + std::to_string(i));
      if (!s || s->counters.cycles != counted[i]) return false;
    }
    return true;
  };
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (!exact() && std::chrono::steady_clock::now() < until) {
    d.step();
    std::this_thread::sleep_for(5ms);
  }
  for (std::size_t i = 0; i < kProcesses; ++i) {
    const auto s = d.aggregator().find("p" + std::to_string(i));
    REQUIRE(s.has_value());
    INFO("component p" << i);
    CHECK(s->counters.cycles == counted[i]);
    CHECK(s->state == TaskState::Stopped);
  }
  // Not the components' fault: no deadline event, nothing corrupted or rejected.
  CHECK(events_of(d, events, EventKind::Deadline).empty());
  CHECK(events_of(d, events, EventKind::SegmentCorrupted).empty());
  CHECK(events_of(d, events, EventKind::SegmentRejected).empty());
}
