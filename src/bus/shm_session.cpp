// The process side: segment creation, the exit records, clean-up when no daemon drains.
#include "vigil/bus/shm_session.hpp"

#include <fmt/format.h>

#include <array>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <mutex>

#include "vigil/bus/shm_segment.hpp"
#include "vigil/platform/process_watch.hpp"

namespace vigil::bus {

namespace {

// The live segments of this process, for the exit recorder (which runs in a signal handler or
// at exit: no allocation, no lock). A slot's name is written before its header is published.
constexpr int kMaxLive = 4096;
struct LiveSlot {
  std::atomic<ShmSegmentHeader*> header{nullptr};
  char name[64] = {};
};
std::array<LiveSlot, kMaxLive> g_live;
std::atomic<int> g_recording{0};  // recorders running: a segment is unmapped only when 0
std::mutex g_live_mutex;          // serialises slot allocation (not used by the recorder)

bool unattended(const ShmSegmentHeader& h) noexcept {
  const auto hb = std::atomic_ref<std::int64_t>(const_cast<std::int64_t&>(h.daemon_heartbeat_ns))
                      .load(std::memory_order_relaxed);
  return hb == 0 || platform::now_ns() - hb > kShmOrphanAfter;
}

// Async-signal-safe: stores only (plus shm_unlink at a normal exit, outside any signal).
void record_exit(platform::ExitStatus::Kind kind, int code) noexcept {
  g_recording.fetch_add(1);
  const ShmExit k =
      kind == platform::ExitStatus::Kind::Exited ? ShmExit::Exited : ShmExit::Signaled;
  const auto me = platform::current_pid();  // async-signal-safe
  for (LiveSlot& s : g_live) {
    ShmSegmentHeader* h = s.header.load();
    // A child made by fork() inherits its parent's mappings and this table: never record the
    // child's end in the parent's segments.
    if (h == nullptr || h->pid != me) continue;
    std::atomic_ref<std::int32_t>(h->exit_code).store(code, std::memory_order_relaxed);
    std::atomic_ref<std::uint32_t>(h->exit_kind)
        .store(static_cast<std::uint32_t>(k), std::memory_order_release);
    // A normal exit with no daemon to read the segments: leave nothing behind. A death by a
    // signal keeps them, so that a daemon started later can still report it.
    if (k == ShmExit::Exited && unattended(*h)) (void)platform::unlink_shared_memory(s.name);
  }
  g_recording.fetch_sub(1);
}

int register_live(ShmSegmentHeader* h, const std::string& name) {
  std::lock_guard lock(g_live_mutex);
  for (int i = 0; i < kMaxLive; ++i) {
    LiveSlot& s = g_live[static_cast<std::size_t>(i)];
    if (s.header.load() != nullptr) continue;
    const std::size_t n = std::min(name.size(), sizeof s.name - 1);
    std::memcpy(s.name, name.data(), n);
    s.name[n] = '\0';
    s.header.store(h);
    return i;
  }
  return -1;  // more than kMaxLive segments: this one's exit is not recorded (pidfd still is)
}

void unregister_live(int slot) {
  if (slot < 0) return;
  {
    std::lock_guard lock(g_live_mutex);
    g_live[static_cast<std::size_t>(slot)].header.store(nullptr);
  }
  // A recorder that loaded the pointer before it was cleared finishes before the unmap.
  while (g_recording.load() != 0) {
  }
}

}  // namespace

expected<std::optional<ShmOptions>, Error> shm_options_from_environment() {
  const char* name = std::getenv("VIGIL_SUPERVISOR");
  if (name == nullptr || *name == '\0') return std::optional<ShmOptions>{};
  if (!valid_supervisor_name(name)) {
    return unexpected<Error>(
        Error(EINVAL, fmt::format("VIGIL_SUPERVISOR='{}' is not a supervisor name "
                                  "(1 to 31 of A-Z a-z 0-9 _ -)",
                                  name)));
  }
  ShmOptions o;
  o.name = name;
  if (const char* g = std::getenv("VIGIL_SUPERVISOR_GROUP"); g != nullptr && *g != '\0') {
    o.group = g;
  }
  return std::optional<ShmOptions>(std::move(o));
}

ShmSegment::ShmSegment(platform::SharedMemory memory, ShmGeometry geometry)
    : memory_(std::move(memory)), geometry_(geometry) {
  slot_ = register_live(static_cast<ShmSegmentHeader*>(memory_.data()), memory_.name());
}

ShmSegment::~ShmSegment() {
  auto* h = static_cast<ShmSegmentHeader*>(memory_.data());
  if (h == nullptr) return;
  unregister_live(slot_);
  if (h->pid != platform::current_pid()) return;  // a forked child's copy
  std::atomic_ref<std::uint32_t>(h->state).store(static_cast<std::uint32_t>(ShmState::Closed),
                                                 std::memory_order_release);
  if (unattended(*h)) (void)memory_.unlink();
}

ShmSession::ShmSession(ShmOptions options, ShmSchema schema)
    : options_(std::move(options)), schema_(schema) {}

expected<std::shared_ptr<ShmSession>, Error> ShmSession::open(ShmOptions options,
                                                              ShmSchema schema) {
  if (!valid_supervisor_name(options.name)) {
    return unexpected<Error>(Error(EINVAL, fmt::format("supervisor name '{}' is not 1 to 31 of "
                                                       "A-Z a-z 0-9 _ -",
                                                       options.name)));
  }
  if (!options.group.empty() && !platform::group_id(options.group)) {
    return unexpected<Error>(
        Error(EINVAL, fmt::format("group '{}' does not exist", options.group)));
  }
  if (schema.type_count == 0 || schema.type_count > kShmMaxTypes ||
      schema.payload_size > kShmMaxPayload) {
    return unexpected<Error>(Error(EINVAL, "message schema out of the segment format's bounds"));
  }
  platform::install_exit_recorder(&record_exit);
  return std::shared_ptr<ShmSession>(new ShmSession(std::move(options), schema));
}

std::uint32_t ShmSession::created() const {
  std::lock_guard lock(mutex_);
  return next_index_;
}

void ShmSession::report(const std::string& message) const {
  if (options_.on_error) {
    options_.on_error(message);
  } else {
    std::fprintf(stderr, "%s\n", message.c_str());
  }
}

expected<std::unique_ptr<ShmSegment>, Error> ShmSession::create(std::string_view component,
                                                                std::uint32_t capacity) {
  std::uint32_t index = 0;
  {
    std::lock_guard lock(mutex_);
    index = next_index_++;
  }
  const platform::ProcessIdentity me = platform::self_identity();
  const ShmGeometry g =
      ShmGeometry::make(schema_.type_count, schema_.payload_size, std::max(capacity, 1U));
  const std::string name = shm_segment_name(options_.name, me.pid, index);
  platform::ShmCreateOptions co;
  co.group = options_.group;
  auto mem = platform::SharedMemory::create(name, g.segment_size, co);
  if (!mem && mem.error().code == EEXIST) {
    // Left by a dead process that had this pid (the pid is ours now, so it is dead).
    (void)platform::unlink_shared_memory(name);
    mem = platform::SharedMemory::create(name, g.segment_size, co);
  }
  if (!mem) return unexpected<Error>(mem.error());
  const std::string process_name = platform::self_process_name();
  const std::string command_line = platform::self_command_line(255);
  ShmIdentity who;
  who.supervisor_name = options_.name;
  who.component_name = component;
  who.component_index = index;
  who.pid = me.pid;
  who.uid = platform::effective_uid();
  who.start_ticks = me.start_ticks;
  who.created_unix_ns = platform::unix_now_ns();
  who.process_name = process_name;
  who.command_line = command_line;
  init_shm_segment(mem->data(), g, schema_, who);
  return std::make_unique<ShmSegment>(std::move(*mem), g);
}

}  // namespace vigil::bus
