// The components of the simulated robot. Each is a plain vigil::Task<Derived>: the supervision
// the demo shows comes from the one base class, not from code in these components. What they
// say themselves goes through VIGIL_LOG_* (RT-safe: formatted later, on the supervisor thread).
#include "demo_components.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "vigil/can/sniffer.hpp"
#include "vigil/deploy/can_extension.hpp"
#include "vigil/deploy/system.hpp"
#include "vigil/log/log.hpp"
#include "vigil/platform/clock.hpp"

namespace vigil::demo {

void burn(Nanos ns) noexcept {
  const Nanos end = platform::now_ns() + ns;
  while (platform::now_ns() < end) {
  }
}

namespace {

using deploy::ComponentContext;

Nanos param_duration(const ComponentContext& c, std::string_view key, Nanos fallback) {
  return c.parameters.defined() ? c.parameters.optional_duration(key, fallback) : fallback;
}
template <class T>
T param(const ComponentContext& c, std::string_view key, T fallback) {
  return c.parameters.defined() ? c.parameters.optional(key, fallback) : fallback;
}

/// A motor controller: a PD law on a simulated motor, a few microseconds of work.
class Motor : public Task<Motor> {
 public:
  explicit Motor(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        kp_(param(c, "kp", 40.0)),
        kd_(param(c, "kd", 2.0)),
        work_ns_(param_duration(c, "work", 20 * kNanosPerMicro)) {}
  void on_update() {
    const double target = std::sin(static_cast<double>(cycles()) * 1e-3);
    const double torque = kp_ * (target - position_) - kd_ * velocity_;
    velocity_ += torque * 1e-3;
    position_ += velocity_ * 1e-3;
    burn(work_ns_);
  }
  /// The fallback while the safe state is requested (vigil/safe_state.hpp): hold the position,
  /// damping the motion out. Runs instead of on_update().
  void on_safe_state() {
    const double torque = -kd_ * velocity_ * 10.0;
    velocity_ += torque * 1e-3;
    position_ += velocity_ * 1e-3;
    burn(work_ns_ / 2);
  }

 private:
  double kp_, kd_;
  Nanos work_ns_;
  double position_ = 0, velocity_ = 0;
};

/// Sensor fusion: a complementary filter over a simulated IMU.
class Fusion : public Task<Fusion> {
 public:
  explicit Fusion(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        work_ns_(param_duration(c, "work", 60 * kNanosPerMicro)) {}
  void on_update() {
    const double gyro = 0.01 * std::cos(static_cast<double>(cycles()) * 2e-3);
    const double accel = std::atan2(std::sin(angle_), std::cos(angle_));
    angle_ = 0.98 * (angle_ + gyro * 2e-3) + 0.02 * accel;
    burn(work_ns_);
  }

 private:
  Nanos work_ns_;
  double angle_ = 0;
};

/// A planner at 10 Hz on SCHED_OTHER: a millisecond or two of work, allocations allowed.
class Planner : public Task<Planner> {
 public:
  explicit Planner(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        work_ns_(param_duration(c, "work", 2 * kNanosPerMilli)) {}
  void on_update() {
    waypoints_.assign(64, 0.0);  // planners allocate; this one is not on a real-time policy
    for (std::size_t i = 0; i < waypoints_.size(); ++i) waypoints_[i] = std::sqrt(double(i));
    burn(work_ns_);
  }

 private:
  Nanos work_ns_;
  std::vector<double> waypoints_;
};

/// Injected fault: an execution time that ramps from `from` to `to` (fractions of `period`)
/// over `over`, as a slowly growing load does. The EWMA-based overrun check flags it early.
class LoadRamp : public Task<LoadRamp> {
 public:
  explicit LoadRamp(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        period_ns_(param_duration(c, "period", 2 * kNanosPerMilli)),
        from_(param(c, "from", 0.2)),
        to_(param(c, "to", 0.98)),
        over_ns_(param_duration(c, "over", 6 * kNanosPerSecond)) {}
  bool on_start() {
    start_ns_ = platform::now_ns();
    return true;
  }
  void on_update() {
    const double t = std::min(
        1.0, static_cast<double>(platform::now_ns() - start_ns_) / static_cast<double>(over_ns_));
    const double share = from_ + (to_ - from_) * t;
    if (!announced_) {
      announced_ = true;
      VIGIL_LOG_INFO("load ramps from {:.0f}% to {:.0f}% of the {} us period over {:.1f} s",
                     from_ * 100, to_ * 100, period_ns_ / kNanosPerMicro,
                     static_cast<double>(over_ns_) * 1e-9);
    }
    // Warn at each 5% step from 80% of the period: the cycle is running out of time.
    const int step = static_cast<int>(share * 20);  // in 5% steps
    if (step >= 16 && step > warned_step_) {
      warned_step_ = step;
      VIGIL_LOG_WARN("execution time at {:.0f}% of the period ({} us of {} us)", share * 100,
                     static_cast<Nanos>(share * static_cast<double>(period_ns_)) / kNanosPerMicro,
                     period_ns_ / kNanosPerMicro);
    }
    burn(static_cast<Nanos>(share * static_cast<double>(period_ns_)));
  }

 private:
  Nanos period_ns_;
  double from_, to_;
  Nanos over_ns_;
  Nanos start_ns_ = 0;
  bool announced_ = false;
  int warned_step_ = 0;
};

/// Injected fault: allocates on every `every`-th cycle (a real-time loss on a FIFO thread).
class Leaky : public Task<Leaky> {
 public:
  explicit Leaky(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        every_(param<std::uint64_t>(c, "every", 1000)),
        sample_(declare_checkpoint("sample")) {}
  void on_update() {
    if (++n_ % every_ == 0) {
      log_.push_back(std::make_unique<double>(static_cast<double>(n_)));  // the hidden allocation
      if (log_.size() > 16) log_.clear();
    }
    burn(5 * kNanosPerMicro);
    checkpoint(sample_);  // the demo's deadline chain starts here (the encoder ends it)
  }

 private:
  std::uint64_t every_;
  CheckpointId sample_;
  std::uint64_t n_ = 0;
  std::vector<std::unique_ptr<double>> log_;
};

/// Injected fault: throws after `after` (an encoder that starts returning garbage). A frame it
/// decodes passes checkpoint "decoded" (the end of the demo's deadline chain).
class Faulty : public Task<Faulty> {
 public:
  explicit Faulty(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        after_ns_(param_duration(c, "after", 4 * kNanosPerSecond)),
        decoded_(declare_checkpoint("decoded")) {}
  bool on_start() {
    start_ns_ = platform::now_ns();
    return true;
  }
  void on_update() {
    ++frame_;
    // The encoder's frame: a position and its checksum (garbage once the fault starts).
    const std::uint16_t position = static_cast<std::uint16_t>(frame_ * 7);
    const std::uint16_t expected = checksum(position);
    const bool broken = platform::now_ns() - start_ns_ > after_ns_;
    const std::uint16_t got = broken ? static_cast<std::uint16_t>(expected ^ 0x5A5A) : expected;
    if (got != expected) {
      VIGIL_LOG_ERROR("joint {}: encoder frame {} checksum {:#06x}, expected {:#06x}", 3, frame_,
                      got, expected);
      throw std::runtime_error("encoder checksum mismatch on joint 3");
    }
    burn(10 * kNanosPerMicro);
    checkpoint(decoded_);
  }

 private:
  static std::uint16_t checksum(std::uint16_t v) noexcept {
    return static_cast<std::uint16_t>((v * 0x9E37U) ^ 0xA5A5U);
  }

  Nanos after_ns_;
  CheckpointId decoded_;
  Nanos start_ns_ = 0;
  std::uint64_t frame_ = 0;
};

/// Telemetry: publishes a sample every `every`-th cycle (checkpoint "publish": 100 Hz on a 1 kHz
/// thread by default). Injected fault: from `burst_after` on it publishes every cycle (a state
/// machine stuck in its resend state): a component that runs too often. 0s: never.
class Telemetry : public Task<Telemetry> {
 public:
  explicit Telemetry(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        every_(param<std::uint64_t>(c, "every", 10)),
        burst_after_ns_(param_duration(c, "burst_after", 0)),
        publish_(declare_checkpoint("publish")) {
    if (every_ == 0) throw std::runtime_error("every must be at least 1");
  }
  bool on_start() {
    start_ns_ = platform::now_ns();
    return true;
  }
  void on_update() {
    const bool burst = burst_after_ns_ > 0 && platform::now_ns() - start_ns_ > burst_after_ns_;
    if (burst && !announced_) {
      announced_ = true;
      VIGIL_LOG_WARN("resending every cycle (state machine stuck in RESEND)");
    }
    if (burst || ++n_ % every_ == 0) {
      burn(2 * kNanosPerMicro);  // serialise and hand the sample over
      checkpoint(publish_);
    }
  }

 private:
  std::uint64_t every_;
  Nanos burst_after_ns_;
  CheckpointId publish_;
  Nanos start_ns_ = 0;
  std::uint64_t n_ = 0;
  bool announced_ = false;
};

/// A driver for a device that is not there (`device`): it configures, but refuses to start. In
/// the demo it is `optional` (the system runs without it) and health supervision expects it to
/// run: its alive supervision reports that it never started.
class MissingDevice : public Task<MissingDevice> {
 public:
  explicit MissingDevice(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        device_(param<std::string>(c, "device", "/dev/lidar0")) {}
  [[nodiscard]] const std::string& device() const noexcept { return device_; }
  bool on_start() { return false; }  // the device is not there
  void on_update() {}

 private:
  std::string device_;
};

/// Fault injection: after `after`, on_update never returns (a driver call that hangs). The other
/// components of its activity's thread starve with it; the monitor reports them STALE, and
/// `vigil demo` cannot join that thread when it stops (it exits with code 4 after 5 s).
class Stuck : public Task<Stuck> {
 public:
  explicit Stuck(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        after_ns_(param_duration(c, "after", 2 * kNanosPerSecond)) {}
  bool on_start() {
    start_ns_ = platform::now_ns();
    return true;
  }
  void on_update() {
    if (platform::now_ns() - start_ns_ > after_ns_) {
      for (;;) std::this_thread::sleep_for(std::chrono::hours(1));
    }
    burn(10 * kNanosPerMicro);
  }

 private:
  Nanos after_ns_;
  Nanos start_ns_ = 0;
};

/// Fault injection: once, after `after`, on_update blocks for `for` (a driver call that times
/// out), then the component runs normally again. The watchdog reports it within its deadline
/// (max(10 periods, 30 ms) by default) and reports its recovery. Each cycle passes three
/// checkpoints, command -> move -> report; the cycle that timed out drops its move (command ->
/// report), which the demo's logical supervision catches.
class Hang : public Task<Hang> {
 public:
  explicit Hang(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        after_ns_(param_duration(c, "after", 1500 * kNanosPerMilli)),
        for_ns_(param_duration(c, "for", 300 * kNanosPerMilli)),
        command_(declare_checkpoint("command")),
        move_(declare_checkpoint("move")),
        report_(declare_checkpoint("report")) {}
  bool on_start() {
    start_ns_ = platform::now_ns();
    return true;
  }
  void on_update() {
    checkpoint(command_);
    if (!hung_ && platform::now_ns() - start_ns_ > after_ns_) {
      hung_ = true;
      VIGIL_LOG_WARN("driver call blocks for {} ms; this cycle's move is dropped",
                     for_ns_ / kNanosPerMilli);
      std::this_thread::sleep_for(std::chrono::nanoseconds(for_ns_));  // the injected fault
    } else {
      burn(10 * kNanosPerMicro);
      checkpoint(move_);
    }
    checkpoint(report_);
  }

 private:
  Nanos after_ns_;
  Nanos for_ns_;
  CheckpointId command_, move_, report_;
  Nanos start_ns_ = 0;
  bool hung_ = false;
};

/// A CAN I/O component: every millisecond it sends SYNC and one RPDO1 (control word) to each of
/// `drives` simulated CANopen drives and reads their TPDO1 answers, timing every driver call into
/// the sniffer of the deployment's CAN supervision. Drive `silent_node` stops answering after
/// `silent_after`.
/// A queue of frames from the reactions (any thread, rarely) to the CAN I/O's real-time loop:
/// producers take a mutex (never on a real-time thread); the loop pops without one.
class FrameQueue {
 public:
  bool push(const can::Frame& f) {
    const std::lock_guard lock(producers_);
    const std::uint32_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= frames_.size()) return false;
    frames_[head % frames_.size()] = f;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  bool pop(can::Frame& f) noexcept {  // RT-safe: the CAN I/O's thread only
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    f = frames_[tail % frames_.size()];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

 private:
  std::mutex producers_;
  std::array<can::Frame, 16> frames_{};
  std::atomic<std::uint32_t> head_{0};
  std::atomic<std::uint32_t> tail_{0};
};

/// CAN I/O with simulated CANopen drives: every cycle a SYNC, an RPDO to each drive and each
/// drive's TPDO answer. The drives obey NMT commands (CiA 301 7.2.8.3.1: 0x000 [command, node]):
/// a stopped drive answers no PDO, only its heartbeat (0x700 + node, "stopped"). Registers the CAN
/// writer `can_io` through which reactions send frames (vigil/service/reactions.hpp).
class CanIo : public Task<CanIo> {
 public:
  explicit CanIo(const ComponentContext& c)
      : Task(c.name, c.supervision, c.registry()),
        drives_(param<std::uint32_t>(c, "drives", 8)),
        silent_node_(param<std::uint32_t>(c, "silent_node", 5)),
        silent_after_ns_(param_duration(c, "silent_after", 3 * kNanosPerSecond)) {
    auto* ext = c.system != nullptr ? c.system->extension<deploy::CanExtension>() : nullptr;
    if (ext == nullptr) {
      throw std::runtime_error("demo.can_io needs a `can:` section in the deployment");
    }
    sniffer_ = std::make_unique<can::Sniffer<256>>(
        ext->registry(), c.name,
        can::SnifferOptions{.max_ids = 64, .node_map = can::NodeMap::canopen()});
    if (auto ok = sniffer_->set_filter(ext->config().filter); !ok) {
      throw std::runtime_error("CAN filter: " + ok.error().message);
    }
    if (drives_ == 0 || drives_ > 127) throw std::runtime_error("drives must be 1..127");
    state_.fill(kOperational);
    c.system->service().reactions().add_can_writer(
        c.name, [q = queue_](const can::Frame& f) { return q->push(f); });
  }
  bool on_start() {
    start_ns_ = platform::now_ns();
    return true;
  }
  void on_update() {
    const bool silent_phase = platform::now_ns() - start_ns_ > silent_after_ns_;
    for (can::Frame f; queue_->pop(f);) {  // frames the reactions sent: on the bus, then obeyed
      send(f);
      obey(f);
    }
    send(can::Frame::classic(0x080, {}));  // SYNC
    pending_ = 0;
    for (std::uint32_t node = 1; node <= drives_; ++node) {
      send(can::Frame::classic(0x200 + node, {0x0F, 0x00, 0x00, 0x10}));  // RPDO1: control word
      if (silent_phase && node == silent_node_) {
        // Every cycle while the drive is silent: at Debug, and rate-limited by the supervisor.
        VIGIL_LOG_DEBUG("drive {} (node {:#04x}): no TPDO1 answer", node, 0x180 + node);
      } else {
        // TPDO1 (status word) while operational; a drive stopped by NMT answers the SYNC with
        // its heartbeat instead (a simplification: a real drive beats at its own period).
        answers_[pending_++] = state_[node] == kOperational ? 0x180 + node : 0x700 + node;
      }
    }
    if (silent_phase && !reported_silent_) {
      reported_silent_ = true;
      VIGIL_LOG_WARN("drive {} stopped answering (no TPDO1 since the SYNC of this cycle)",
                     silent_node_);
    }
    for (std::uint32_t i = 0; i < pending_; ++i) {  // the drives' frames
      const Nanos t0 = platform::now_ns();
      burn(2 * kNanosPerMicro);  // the driver's read call
      const std::uint32_t id = answers_[i];
      can::Frame f = id >= 0x700 ? can::Frame::classic(id, {state_[id - 0x700]})
                                 : can::Frame::classic(id, {0x27, 0x06, 0x00, 0x10});
      const Nanos t1 = platform::now_ns();
      f.timestamp = t1;
      sniffer_->on_read(f, t0, t1);
    }
  }

 private:
  static constexpr std::uint8_t kOperational = 0x05, kStopped = 0x04, kPreOperational = 0x7F;

  void send(can::Frame f) {
    const Nanos t0 = platform::now_ns();
    burn(3 * kNanosPerMicro);  // the driver's write call
    const Nanos t1 = platform::now_ns();
    f.timestamp = t1;
    sniffer_->on_write(f, t0, t1);
  }
  // An NMT command (id 0, [command, node]; node 0: all) changes the simulated drives' state.
  void obey(const can::Frame& f) noexcept {
    if (f.id != 0 || f.length != 2) return;
    const std::uint8_t to = f.data[0] == 0x01   ? kOperational
                            : f.data[0] == 0x02 ? kStopped
                            : f.data[0] == 0x80 ? kPreOperational
                                                : 0;
    if (to == 0) return;
    for (std::uint32_t node = 1; node <= drives_; ++node) {
      if (f.data[1] == 0 || f.data[1] == node) state_[node] = to;
    }
  }

  std::uint32_t drives_;
  std::uint32_t silent_node_;
  Nanos silent_after_ns_;
  Nanos start_ns_ = 0;
  std::unique_ptr<can::Sniffer<256>> sniffer_;
  std::shared_ptr<FrameQueue> queue_ = std::make_shared<FrameQueue>();
  std::array<std::uint8_t, 128> state_{};
  std::array<std::uint32_t, 128> answers_{};
  std::uint32_t pending_ = 0;
  bool reported_silent_ = false;
};

}  // namespace

void register_components() {
  auto& f = deploy::ComponentFactory::instance();
  f.add<Motor>("demo.motor", "motor controller: PD law on a simulated motor");
  f.add<Fusion>("demo.fusion", "sensor fusion: complementary filter on a simulated IMU");
  f.add<Planner>("demo.planner", "trajectory planner (allocates; for SCHED_OTHER)");
  f.add<LoadRamp>("demo.load_ramp", "fault: execution time ramping toward the period");
  f.add<Leaky>("demo.leaky", "fault: allocates every N cycles");
  f.add<Faulty>("demo.faulty", "fault: throws after a delay");
  f.add<Stuck>("demo.stuck", "fault: never returns from on_update after a delay");
  f.add<Hang>("demo.hang", "fault: blocks once in on_update for a while, then recovers");
  f.add<Telemetry>("demo.telemetry", "telemetry publisher (fault: publishes every cycle)");
  f.add<MissingDevice>("demo.missing_device", "driver of an absent device: refuses to start");
  f.add<CanIo>("demo.can_io", "CAN I/O with simulated CANopen drives (needs a `can:` section)");
  deploy::register_can_extension();  // also done by linking vigil::deploy_can
}

const char* const kDemoDeployment =
    R"(# vigil demo: a small simulated robot (print it with `vigil demo --print-config`).
name: demo-robot
activities:
  - {name: control, period: 1ms, policy: FIFO, priority: 80, cpu: 1}
  - {name: fusion, period: 2ms, policy: FIFO, priority: 70, cpu: 1}
  - {name: planning, period: 100ms, policy: OTHER}
  # SCHED_OTHER: a FIFO thread near 100% of a CPU would trigger the kernel's RT throttling.
  - {name: ramp, period: 2ms, policy: OTHER}
  - {name: aux, period: 1ms, policy: FIFO, priority: 50, cpu: 0}
  - {name: io, period: 1ms, policy: FIFO, priority: 75, cpu: 0}
  - {name: drive, period: 1ms, policy: FIFO, priority: 60, cpu: 0}
components:
  - {name: motor_left, type: demo.motor, activity: control}
  - {name: motor_right, type: demo.motor, activity: control}
  - {name: sensor_fusion, type: demo.fusion, activity: fusion}
  - {name: planner, type: demo.planner, activity: planning}
  - name: load_ramp
    type: demo.load_ramp
    activity: ramp
    parameters: {period: 2ms, from: 0.2, to: 0.98, over: 6s}
  - name: logger
    type: demo.leaky
    activity: aux
    detectors: [allocation]
    parameters: {every: 1000}
  - name: encoder
    type: demo.faulty
    activity: aux
    parameters: {after: 2500ms}
  - name: telemetry                       # publishes at 100 Hz; every cycle from 3.2 s
    type: demo.telemetry
    activity: aux
    parameters: {every: 10, burst_after: 3200ms}
  - name: lidar                           # its device is absent: it never starts
    type: demo.missing_device
    activity: planning
    optional: true                        # the system runs without it
    parameters: {device: /dev/lidar0}
  - name: gripper
    type: demo.hang
    activity: drive
    parameters: {after: 1500ms, for: 300ms}
  - name: can_io
    type: demo.can_io
    activity: io
    parameters: {drives: 8, silent_node: 5, silent_after: 3s}
supervision:
  supervisor_period: 10ms
  monitor_period: 1s
  ewma_weight: 0.05
  warmup: 100ms                           # start-up cycles: counted, kept out of statistics
  watchdog: {periods: 10, floor: 30ms}    # a 1 kHz component is silent after 30 ms
  events: {auto_clear: 0s}                # latched faults stay until cleared
  flight_recorder: {cycles: 1024, min_interval: 10s}
  thresholds:
    defaults:
      window: 2s
      # A shared 2-vCPU machine delays a real-time thread now and then: warn from 1% overruns.
      overrun: {warn_rate: 0.01, error_rate: 0.1}
      # The simulated workloads are tiny (5-60 us): supervision is ~1% of them in a release
      # build, but several times more in a sanitizer build. Warn from 20%.
      overhead: {warn_share: 0.2}
can:
  node_map: canopen
  filter: {not: {ids: [0x080]}}   # SYNC is nobody's traffic
  buses: {all: {bitrate: 500k}}   # bus load in percent (vigil_can_bus_load_ratio)
  defaults:
    not_responding: {after: 100ms}
    rx_gap: {warn: 5ms, error: 50ms, stat: p99}
  nodes:
    drive_1: {node: 1, bus: 0}
    drive_2: {node: 2, bus: 0}
    drive_3: {node: 3, bus: 0}
    drive_4: {node: 4, bus: 0}
    drive_5: {node: 5, bus: 0}
    drive_6: {node: 6, bus: 0}
    drive_7: {node: 7, bus: 0}
    drive_8: {node: 8, bus: 0}
  groups:
    left_arm: {node_range: [1, 4], bus: 0}
    right_arm: {node_range: [5, 8], bus: 0}
health:                                   # checkpoints supervised (docs/guide/health-supervision.md)
  alive:
    - {name: telemetry_rate, checkpoint: telemetry.publish, reference_cycle: 100ms,
       expected: 10, min_margin: 3, max_margin: 3, tolerance: 1}
    - {name: lidar_alive, checkpoint: lidar, reference_cycle: 500ms, expected: 5,
       min_margin: 1, max_margin: 1, startup_grace: 1s}
  deadline:
    - {name: sample_to_decode, start: logger.sample, end: encoder.decoded, max: 5ms,
       tolerance: 2}
  logical:
    - name: gripper_sequence
      initial: gripper.command
      final: gripper.report
      transitions: ["gripper.command -> gripper.move", "gripper.move -> gripper.report"]
reactions:                                # what vigil does about faults (docs/guide/reactions.md)
  rules:
    - name: encoder_fault                 # the motors switch to their hold fallback
      on: {event: exception, component: encoder}
      safe_state: true
    - name: stop_right_arm                # drive_5 is silent: stop the right arm's drives
      on: {event: not_responding, component: can0/drive_5}
      can:                                # CANopen NMT "stop remote node" (CiA 301)
        - {writer: can_io, id: 0x000, data: [0x02, 5]}
        - {writer: can_io, id: 0x000, data: [0x02, 6]}
        - {writer: can_io, id: 0x000, data: [0x02, 7]}
        - {writer: can_io, id: 0x000, data: [0x02, 8]}
outputs: {}
)";

}  // namespace vigil::demo
