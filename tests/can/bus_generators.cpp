#include "bus_generators.hpp"

#include <algorithm>
#include <array>
#include <functional>

#include "vigil/can/log/candump.hpp"
#include "vigil/can/node_map.hpp"

namespace vigil::can::test {

namespace {

// SplitMix64: a small deterministic generator for jitter.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [-max, max].
  Nanos jitter(Nanos max) {
    if (max <= 0) return 0;
    return static_cast<Nanos>(next() % static_cast<std::uint64_t>(2 * max + 1)) - max;
  }
  /// Uniform in [lo, hi].
  Nanos between(Nanos lo, Nanos hi) { return lo + static_cast<Nanos>(next() % (hi - lo + 1)); }

 private:
  std::uint64_t state_;
};

// Collects frames at times relative to the capture's start, then sorts them.
class Capture {
 public:
  Capture(Nanos duration, std::optional<NodeStop> stop, std::uint64_t seed)
      : duration_(duration), stop_(stop), rng_(seed) {}

  Rng& rng() { return rng_; }
  [[nodiscard]] Nanos duration() const { return duration_; }

  /// Whether `node` still runs at `t`.
  [[nodiscard]] bool alive(std::uint32_t node, Nanos t) const {
    return !stop_ || stop_->node != node || t < stop_->at;
  }

  void add(Nanos t, Frame f) {
    if (t < 0 || t >= duration_) return;
    f.timestamp = kCaptureStart + t;
    out_.push_back(LogEntry{f, std::nullopt});
  }

  /// Calls `f(t)` at `from + k * period` (+ jitter up to `jitter`) until `until`.
  void every(Nanos period, Nanos jitter, Nanos from, Nanos until,
             const std::function<void(Nanos)>& f) {
    for (Nanos t = from; t < until; t += period) f(t + rng_.jitter(jitter));
  }

  std::vector<LogEntry> take() {
    std::stable_sort(out_.begin(), out_.end(), [](const LogEntry& a, const LogEntry& b) {
      return a.frame.timestamp < b.frame.timestamp;
    });
    return std::move(out_);
  }

 private:
  Nanos duration_;
  std::optional<NodeStop> stop_;
  Rng rng_;
  std::vector<LogEntry> out_;
};

constexpr Nanos ms(std::int64_t v) { return v * kNanosPerMilli; }
constexpr Nanos us(std::int64_t v) { return v * kNanosPerMicro; }
constexpr Nanos s(std::int64_t v) { return v * kNanosPerSecond; }

Frame ext(std::uint32_t id, std::initializer_list<std::uint8_t> data) {
  return Frame::classic(id, data, IdFormat::Extended);
}

}  // namespace

std::vector<LogEntry> canopen_capture(const CanOpenBus& bus) {
  Capture c(bus.duration, bus.stop, bus.seed);
  const Nanos end = bus.duration;
  c.add(0, Frame::classic(0x000, {0x01, 0x00}));  // NMT: start every node
  // SYNC from the master every 100 ms.
  c.every(ms(100), us(200), ms(5), end, [&](Nanos t) { c.add(t, Frame::classic(0x080, {})); });
  // Heartbeats of nodes 1-4 (operational), every 1.4 s with 5 ms of jitter.
  for (std::uint32_t node = 1; node <= 4; ++node) {
    c.every(bus.heartbeat, ms(5), ms(50) * node, end, [&, node](Nanos t) {
      if (c.alive(node, t)) c.add(t, Frame::classic(0x700 + node, {0x05}));
    });
  }
  // TPDO1 of node 1 every 10 ms (8 bytes), of node 2 every 100 ms.
  c.every(ms(10), us(300), ms(2), end, [&](Nanos t) {
    if (c.alive(1, t)) c.add(t, Frame::classic(0x181, {1, 2, 3, 4, 5, 6, 7, 8}));
  });
  c.every(ms(100), us(500), ms(7), end, [&](Nanos t) {
    if (c.alive(2, t)) c.add(t, Frame::classic(0x182, {0x10, 0x20, 0x30, 0x40}));
  });
  // TPDO2 of node 3: event-driven, every 50 ms for a minute, then quiet for three minutes.
  c.every(ms(50), ms(2), ms(11), end, [&](Nanos t) {
    const bool active = t < s(60) || t >= s(240);
    if (active && c.alive(3, t)) c.add(t, Frame::classic(0x283, {0x00, 0x7F}));
  });
  // EMCY of node 2 at 30 s (overcurrent), and its reset one second later.
  if (c.alive(2, s(30))) {
    c.add(s(30), Frame::classic(0x082, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0}));
    c.add(s(31), Frame::classic(0x082, {0, 0, 0, 0, 0, 0, 0, 0}));
  }
  // SDO: every 10 s the master uploads a 140-byte object from node 4 (segmented: an initiate
  // request/response, then 20 segment requests/responses about a millisecond apart).
  c.every(s(10), ms(100), s(3), end, [&](Nanos t0) {
    Nanos t = t0;
    c.add(t, Frame::classic(0x604, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}));
    if (!c.alive(4, t)) return;  // the master times out; it asks again in 10 s
    t += c.rng().between(us(500), ms(2));
    c.add(t, Frame::classic(0x584, {0x41, 0x08, 0x10, 0x00, 140, 0, 0, 0}));
    std::uint8_t toggle = 0;
    for (int seg = 0; seg < 20; ++seg) {
      t += c.rng().between(us(200), us(800));
      c.add(t,
            Frame::classic(0x604, {static_cast<std::uint8_t>(0x60 | toggle), 0, 0, 0, 0, 0, 0, 0}));
      if (!c.alive(4, t)) return;
      t += c.rng().between(us(300), ms(1));
      const std::uint8_t last = seg == 19 ? 0x01 : 0x00;
      c.add(t, Frame::classic(0x584, {static_cast<std::uint8_t>(toggle | last), 'v', 'i', 'g', 'i',
                                      'l', '!', '!'}));
      toggle ^= 0x10;
    }
  });
  // SDO expedited read of node 1's device type every 7 s.
  c.every(s(7), ms(50), s(1), end, [&](Nanos t) {
    c.add(t, Frame::classic(0x601, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
    if (c.alive(1, t)) {
      c.add(t + c.rng().between(us(400), ms(1)),
            Frame::classic(0x581, {0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00}));
    }
  });
  // Node guarding of node 5: the master's RTR every `guard_time`, the node's answer (state 5,
  // operational, with the toggle bit) within a millisecond.
  std::uint8_t toggle = 0;
  c.every(bus.guard_time, ms(2), ms(500), end, [&](Nanos t) {
    c.add(t, Frame::remote(0x705, 1));
    if (!c.alive(5, t)) return;
    c.add(t + c.rng().between(us(200), ms(1)),
          Frame::classic(0x705, {static_cast<std::uint8_t>(toggle | 0x05)}));
    toggle ^= 0x80;
  });
  return c.take();
}

namespace {

// A DroneCAN transfer of `payload` from `source`: one frame when it fits in 7 bytes, else a
// multi-frame transfer (a transfer CRC first, 7 bytes per frame, tail bytes with start, end and
// toggle bits and the transfer ID), frames `spacing` apart. Returns the time after the last.
Nanos transfer(Capture& c, Nanos t, std::uint32_t id, std::vector<std::uint8_t> payload,
               std::uint8_t transfer_id, Nanos spacing) {
  const auto tail = [&](bool start, bool end, bool toggle) {
    return static_cast<std::uint8_t>((start ? 0x80 : 0) | (end ? 0x40 : 0) | (toggle ? 0x20 : 0) |
                                     (transfer_id & 0x1F));
  };
  std::vector<std::uint8_t> bytes;
  if (payload.size() <= 7) {
    bytes = payload;
    bytes.push_back(tail(true, true, false));
    c.add(t, Frame::classic(id, bytes, IdFormat::Extended));
    return t + spacing;
  }
  std::vector<std::uint8_t> stream{0xA5, 0x5A};  // the transfer CRC (not checked by vigil)
  stream.insert(stream.end(), payload.begin(), payload.end());
  bool toggle = false;
  for (std::size_t at = 0; at < stream.size(); at += 7) {
    const std::size_t n = std::min<std::size_t>(7, stream.size() - at);
    bytes.assign(stream.begin() + static_cast<std::ptrdiff_t>(at),
                 stream.begin() + static_cast<std::ptrdiff_t>(at + n));
    bytes.push_back(tail(at == 0, at + n == stream.size(), toggle));
    c.add(t, Frame::classic(id, bytes, IdFormat::Extended));
    toggle = !toggle;
    t += spacing;
  }
  return t;
}

}  // namespace

std::vector<LogEntry> dronecan_capture(const DroneCanBus& bus) {
  namespace dc = dronecan;
  Capture c(bus.duration, bus.stop, bus.seed);
  const Nanos end = bus.duration;
  constexpr std::uint8_t kFc = 10;
  constexpr std::array<std::uint8_t, 4> kEscs{20, 21, 22, 23};
  std::array<std::uint8_t, 128> tid{};  // transfer IDs per source (one counter is enough here)
  const auto next_tid = [&](std::uint8_t node) { return tid[node]++; };
  // The flight controller: NodeStatus every second, esc.RawCommand at 100 Hz.
  c.every(s(1), ms(3), ms(100), end, [&](Nanos t) {
    if (c.alive(kFc, t)) {
      transfer(c, t, dc::message_id(16, 341, kFc), {0x10, 0, 0, 0, 0x00, 0x00, 0x00}, next_tid(kFc),
               us(100));
    }
  });
  c.every(ms(10), us(200), ms(1), end, [&](Nanos t) {
    if (c.alive(kFc, t)) {
      transfer(c, t, dc::message_id(8, 1030, kFc), {0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x07},
               next_tid(kFc), us(100));
    }
  });
  // Each ESC: esc.Status (14 bytes: a 3-frame transfer) at 20 Hz, NodeStatus every second.
  for (const std::uint8_t esc : kEscs) {
    c.every(ms(50), ms(1), ms(3) * esc, end, [&, esc](Nanos t) {
      if (c.alive(esc, t)) {
        transfer(c, t, dc::message_id(16, 1034, esc),
                 {0, 0, 0x10, 0x4C, 0x20, 0x0C, 0xE8, 0x03, 0x00, 0x00, 0x64, 0x00, 0x10, esc},
                 next_tid(esc), us(150));
      }
    });
    c.every(s(1), ms(5), ms(200) + ms(7) * esc, end, [&, esc](Nanos t) {
      if (c.alive(esc, t)) {
        transfer(c, t, dc::message_id(16, 341, esc), {0x10, 0, 0, 0, 0x00, 0x00, 0x00},
                 next_tid(esc), us(100));
      }
    });
  }
  // GetNodeInfo (service 1): the flight controller asks one ESC every 5 s (empty request); the
  // ESC answers with a 52-byte response (an 8-frame transfer).
  int turn = 0;
  c.every(s(5), ms(20), s(2), end, [&](Nanos t) {
    const std::uint8_t esc = kEscs[static_cast<std::size_t>(turn++) % kEscs.size()];
    const std::uint8_t id = next_tid(kFc);
    transfer(c, t, dc::service_id(30, 1, true, esc, kFc), {}, id, us(100));
    if (!c.alive(esc, t)) return;
    std::vector<std::uint8_t> info(50, 0);
    const char* name = "com.example.esc";
    for (std::size_t i = 0; name[i] != 0; ++i) info[35 + i] = static_cast<std::uint8_t>(name[i]);
    transfer(c, t + c.rng().between(ms(1), ms(4)), dc::service_id(30, 1, false, kFc, esc), info, id,
             us(150));
  });
  return c.take();
}

std::vector<LogEntry> j1939_capture(const J1939Bus& bus) {
  Capture c(bus.duration, bus.stop, bus.seed);
  const Nanos end = bus.duration;
  // Engine (0x00): EEC1 every 20 ms, EEC2 every 50 ms, ET1 every second.
  c.every(ms(20), us(800), ms(1), end, [&](Nanos t) {
    if (c.alive(0x00, t)) c.add(t, ext(0x0CF00400, {0xF0, 0x7D, 0x83, 0xC3, 0x12, 0, 0x0F, 0x84}));
  });
  c.every(ms(50), ms(1), ms(3), end, [&](Nanos t) {
    if (c.alive(0x00, t)) c.add(t, ext(0x0CF00300, {0xD1, 0, 0, 0xFF, 0xFF, 0x0F, 0x72, 0x7D}));
  });
  c.every(s(1), ms(1), ms(300), end, [&](Nanos t) {
    if (c.alive(0x00, t))
      c.add(t, ext(0x18FEEE00, {0x7A, 0xFF, 0xA0, 0x28, 0xFF, 0xFF, 0xFF, 0xFF}));
  });
  // Brakes (0x0B): EBC1 every 100 ms.
  c.every(ms(100), ms(2), ms(13), end, [&](Nanos t) {
    if (c.alive(0x0B, t))
      c.add(t, ext(0x18F0010B, {0xC0, 0xFF, 0xF0, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
  });
  // Body controller (0x21): CCVS every 100 ms; a request for the engine hours every 30 s.
  c.every(ms(100), ms(2), ms(29), end, [&](Nanos t) {
    if (c.alive(0x21, t))
      c.add(t, ext(0x18FEF121, {0xF3, 0x00, 0x00, 0x1F, 0xFF, 0xFF, 0xFF, 0xFF}));
  });
  c.every(s(30), ms(10), s(5), end, [&](Nanos t) {
    if (!c.alive(0x21, t)) return;
    c.add(t, ext(0x18EA0021, {0xE5, 0xFE, 0x00}));
    if (c.alive(0x00, t))
      c.add(t + ms(5), ext(0x18FEE500, {0x10, 0x27, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF}));
  });
  return c.take();
}

std::string to_candump(const std::vector<LogEntry>& entries) {
  std::string out;
  for (const LogEntry& e : entries) write_candump_line(out, e.frame, "can0");
  return out;
}

Nanos last_frame_of(const std::vector<LogEntry>& entries, std::uint32_t node, FromNode from) {
  Nanos last = -1;
  for (const LogEntry& e : entries) {
    if (from(e.frame, node)) last = std::max(last, e.frame.timestamp);
  }
  return last;
}

bool canopen_from(const Frame& f, std::uint32_t node) {
  if (f.extended || f.rtr || f.error) return false;
  const NodeAddress a = canopen::map(f.id, false);
  return a.node == node && !a.to_node();
}

bool dronecan_from(const Frame& f, std::uint32_t node) {
  return f.extended && !f.error && dronecan::map(f.id, true).node == node;
}

bool j1939_from(const Frame& f, std::uint32_t node) {
  return f.extended && !f.error && (f.id & 0xFF) == node;
}

}  // namespace vigil::can::test
