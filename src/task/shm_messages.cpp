// vigil::Message over shared memory: the daemon-side check and the "one call" selection.
#include "vigil/task/shm_messages.hpp"
#include "vigil/task/default_registry.hpp"

#include <cstring>
#include <string>
#include <type_traits>

namespace vigil::task {

namespace {

constexpr Nanos kMaxTime = Nanos{1} << 62;

// Reads the byte of a bool without loading it as a bool (a value other than 0/1 is undefined
// behaviour to load).
bool bool_ok(const bool& b) noexcept {
  unsigned char c = 0;
  std::memcpy(&c, &b, 1);
  return c <= 1;
}

template <class E>
bool enum_ok(E e, E last) noexcept {
  using U = std::underlying_type_t<E>;
  return static_cast<U>(e) <= static_cast<U>(last);
}

template <std::size_t N>
void terminate(FixedString<N>& s) noexcept {
  s.data_[N - 1] = '\0';
}

bool time_ok(Nanos t) noexcept { return t >= 0 && t < kMaxTime; }

struct Checker {
  std::string& why;

  bool fail(const char* what) {
    why = what;
    return false;
  }

  bool operator()(TaskInfo& m) {
    terminate(m.name);
    terminate(m.activity);
    if (!bool_ok(m.realtime_refused) || !bool_ok(m.threaded)) {
      return fail("TaskInfo: a bool field is neither 0 nor 1");
    }
    if (!enum_ok(m.requested_policy, SchedPolicy::Fifo) || !enum_ok(m.policy, SchedPolicy::Fifo)) {
      return fail("TaskInfo: scheduling policy out of range");
    }
    if (!enum_ok(m.overrun_policy, OverrunPolicy::Reanchor)) {
      return fail("TaskInfo: overrun policy out of range");
    }
    if (static_cast<std::uint8_t>(m.detectors) > static_cast<std::uint8_t>(Detectors::All)) {
      return fail("TaskInfo: detectors out of range");
    }
    if (!time_ok(m.period_ns)) return fail("TaskInfo: period out of range");
    return true;
  }
  bool operator()(CycleSample& m) {
    if (!bool_ok(m.overrun) || !bool_ok(m.totals_only)) {
      return fail("CycleSample: a bool field is neither 0 nor 1");
    }
    if (!enum_ok(m.state, TaskState::FatalError)) return fail("CycleSample: state out of range");
    if (!time_ok(m.release_ns) || !time_ok(m.start_ns) || !time_ok(m.end_ns) ||
        !time_ok(m.overhead_ns)) {
      return fail("CycleSample: a time is negative or beyond 2^62 ns");
    }
    if (m.end_ns < m.start_ns) return fail("CycleSample: the cycle ends before it starts");
    return true;
  }
  bool operator()(RealTimeLoss& m) {
    if (static_cast<int>(m.cause) >= kLossCauses) return fail("RealTimeLoss: cause out of range");
    return true;
  }
  bool operator()(ExceptionReport& m) {
    terminate(m.type);
    terminate(m.message);
    if (!enum_ok(m.hook, Hook::Cleanup)) return fail("ExceptionReport: hook out of range");
    return true;
  }
  bool operator()(StateChange& m) {
    terminate(m.reason);
    if (!bool_ok(m.refused)) return fail("StateChange: a bool field is neither 0 nor 1");
    if (!enum_ok(m.from, TaskState::FatalError) || !enum_ok(m.to, TaskState::FatalError)) {
      return fail("StateChange: state out of range");
    }
    if (!enum_ok(m.hook, Hook::Cleanup)) return fail("StateChange: hook out of range");
    if (!time_ok(m.time_ns)) return fail("StateChange: time out of range");
    return true;
  }
  bool operator()(health::CheckpointReport& m) {
    terminate(m.name);
    if (!time_ok(m.time_ns)) return fail("CheckpointReport: time out of range");
    if (m.index != health::kMisuseIndex && m.index >= health::kMaxCheckpoints) {
      return fail("CheckpointReport: index out of range");
    }
    if (m.index != health::kMisuseIndex && m.name.empty()) {
      return fail("CheckpointReport: a checkpoint without a name");
    }
    return true;
  }
  // A message type added later is accepted as it is until a check is written for it.
  template <class M>
  bool operator()(M& /*m*/) {
    return true;
  }
};

}  // namespace

bool check_shm_message(Message& m, std::string& why) { return std::visit(Checker{why}, m); }

expected<void, Error> place_in_shared_memory(Registry<Message>& registry, bus::ShmOptions options) {
  options.sticky_types = kShmStickyMessages;
  auto session = bus::ShmSession::open(std::move(options), kShmMessageSchema);
  if (!session) return unexpected<Error>(session.error());
  registry.place_in_shared_memory(
      std::make_shared<Registry<Message>::ShmPortsType>(std::move(*session)));
  return {};
}

expected<void, Error> supervise_in_shared_memory(const std::string& name) {
  bus::ShmOptions o;
  o.name = name;
  return place_in_shared_memory(default_registry(), std::move(o));
}

}  // namespace vigil::task
