// Writes the seed corpus of the shm_segment fuzz target (tests/fuzz/seeds/shm_segment/): segment
// images as a process leaves them (written by the real producer, ShmProducer) and message
// sequences, in the input format of shm_segment_fuzz.cpp. Deterministic (fixed pid, times and
// names), so that CTest (fuzz.seeds.shm_segment) can check that the committed seeds are what this
// writes: when the segment format or a message type changes, that test fails and says to
// regenerate them:
//   build/dev/tests/fuzz/vigil_fuzz_shm_segment_seeds tests/fuzz/seeds/shm_segment
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/task/shm_messages.hpp"

namespace {

using namespace vigil;

// A message with every byte zero, padding included, before its fields are set: the seeds must be
// the same bytes on every run.
template <class T>
T zeroed() {
  T t;
  std::memset(static_cast<void*>(&t), 0, sizeof t);
  return t;
}

task::TaskInfo task_info() {
  auto t = zeroed<task::TaskInfo>();
  t.name = "motor";
  t.activity = "periodic";
  t.requested_policy = SchedPolicy::Fifo;
  t.policy = SchedPolicy::Fifo;
  t.threaded = true;
  t.priority = 80;
  t.cpu = 2;
  t.tid = 4243;
  t.tasks_on_thread = 1;
  t.period_ns = kNanosPerMilli;
  t.port_capacity = 4;
  return t;
}

task::CycleSample sample(std::uint64_t cycle, bool overrun) {
  auto s = zeroed<task::CycleSample>();
  s.release_ns = static_cast<Nanos>(cycle) * kNanosPerMilli;
  s.start_ns = s.release_ns + 20 * kNanosPerMicro;
  s.end_ns = s.start_ns + (overrun ? 1200 : 300) * kNanosPerMicro;
  s.overhead_ns = 900;
  s.overrun = overrun;
  s.counters.cycles = cycle;
  s.counters.overruns = overrun ? 1 : 0;
  return s;
}

task::StateChange state_change(TaskState from, TaskState to) {
  auto c = zeroed<task::StateChange>();
  c.time_ns = kNanosPerSecond;
  c.from = from;
  c.to = to;
  c.hook = Hook::None;
  c.reason = "";
  return c;
}

task::ExceptionReport exception() {
  auto e = zeroed<task::ExceptionReport>();
  e.cycle = 7;
  e.count = 1;
  e.hook = Hook::None;
  e.type = "St13runtime_error";
  e.message = "sensor timeout";
  return e;
}

health::CheckpointReport checkpoint(std::uint64_t count) {
  auto r = zeroed<health::CheckpointReport>();
  r.time_ns = kNanosPerSecond + static_cast<Nanos>(count);
  r.cycle = count;
  r.count = count;
  r.index = 0;
  r.name = "frame_received";
  return r;
}

// A segment of supervisor "fuzz" (the fuzz target's placeholder for its own daemon) written by
// the real producer: the component's identity, its start, samples (the ring holds 4; the rest
// are dropped into the mailboxes), an exception.
std::vector<std::byte> segment(std::int32_t pid, std::uint64_t ticks, std::uint32_t samples) {
  const bus::ShmGeometry g = bus::ShmGeometry::make(task::kShmMessageSchema.type_count,
                                                    task::kShmMessageSchema.payload_size, 4);
  std::vector<std::byte> image(g.segment_size);
  bus::ShmIdentity who;
  who.supervisor_name = "fuzz";
  who.component_name = "motor";
  who.pid = pid;
  who.uid = 1000;
  who.start_ticks = ticks;
  who.created_unix_ns = 1'700'000'000'000'000'000;
  who.process_name = "ctl";
  who.command_line = "ctl --config ctl.yaml";
  bus::init_shm_segment(image.data(), g, task::kShmMessageSchema, who);
  bus::ShmProducer<task::Message> producer(image.data(), g, task::kShmStickyMessages);
  std::uint64_t dropped = 0;
  const auto send = [&](const task::Message& m) {
    if (!producer.push(m)) producer.drop(m, ++dropped);
  };
  send(task_info());
  send(state_change(TaskState::PreOperational, TaskState::Running));
  for (std::uint32_t i = 1; i <= samples; ++i) send(sample(i, i % 3 == 0));
  if (samples > 2) send(exception());
  return image;
}

void write(const std::filesystem::path& dir, const char* name, std::uint8_t mode,
           const std::vector<std::byte>& bytes) {
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out.put(static_cast<char>(mode));
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

template <class T>
void append_message(std::vector<std::byte>& out, std::uint8_t k, const T& m) {
  out.push_back(static_cast<std::byte>(k));
  const auto* p = reinterpret_cast<const std::byte*>(&m);
  out.insert(out.end(), p, p + sizeof m);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIRECTORY\n", argv[0]);
    return 2;
  }
  const std::filesystem::path dir(argv[1]);
  std::filesystem::create_directories(dir);
  // Images (first byte even). pid 4242 + ticks 123: the fuzz target's own (live) process.
  write(dir, "image_live.bin", 0, segment(4242, 123, 2));
  write(dir, "image_full.bin", 0, segment(4242, 123, 9));
  std::vector<std::byte> closed = segment(4242, 123, 3);
  bus::ShmSegmentHeader h;
  std::memcpy(&h, closed.data(), sizeof h);
  h.state = static_cast<std::uint32_t>(bus::ShmState::Closed);
  std::memcpy(closed.data(), &h, sizeof h);
  write(dir, "image_closed.bin", 0, closed);
  // A process that is gone (another pid), which recorded its exit.
  std::vector<std::byte> dead = segment(4243, 77, 5);
  std::memcpy(&h, dead.data(), sizeof h);
  h.exit_kind = static_cast<std::uint32_t>(bus::ShmExit::Signaled);
  h.exit_code = 11;
  std::memcpy(dead.data(), &h, sizeof h);
  write(dir, "image_dead.bin", 0, dead);
  // Half-read: the header alone (truncated), and a segment still being created.
  std::vector<std::byte> header_only(closed.begin(), closed.begin() + sizeof h);
  write(dir, "image_header_only.bin", 0, header_only);
  std::vector<std::byte> creating = segment(4242, 123, 0);
  std::memcpy(&h, creating.data(), sizeof h);
  h.state = static_cast<std::uint32_t>(bus::ShmState::Creating);
  std::memcpy(creating.data(), &h, sizeof h);
  write(dir, "image_creating.bin", 0, creating);

  // Messages (first byte odd; 3: the segment is closed after them).
  std::vector<std::byte> m;
  append_message(m, 0, task_info());
  append_message(m, 4, state_change(TaskState::PreOperational, TaskState::Running));
  for (std::uint64_t i = 1; i <= 5; ++i) append_message(m, 1, sample(i, i == 4));
  append_message(m, 6, checkpoint(1));
  append_message(m, 3, exception());
  write(dir, "messages_run.bin", 1, m);
  std::vector<std::byte> sticky;
  append_message(sticky, 0x80, task_info());
  append_message(sticky, 0x84, state_change(TaskState::Running, TaskState::Stopped));
  append_message(sticky, 0x81, sample(100, true));
  task::RealTimeLoss loss;  // zeroed in place: 16 bytes are returned in registers, padding not kept
  std::memset(static_cast<void*>(&loss), 0, sizeof loss);
  loss.cycle = 3;
  loss.cause = platform::LossCause::Allocation;
  loss.count = 2;
  append_message(sticky, 2, loss);
  append_message(sticky, 1, sample(101, false));
  write(dir, "messages_mailboxes_closed.bin", 3, sticky);
  return 0;
}
