#pragma once
/// @file
/// A CAN capture shaped like real traffic, for the CAN benchmarks when no real capture is given
/// (VIGIL_BENCH_CAN_LOG): a heavy vehicle's SAE J1939 bus, 29-bit identifiers on one interface,
/// written as `candump -l` writes it.
///
/// What is in it (deterministic: the same file on every machine):
///  - 7 nodes (source addresses 0x00 engine, 0x03 transmission, 0x0B brakes, 0x17 instrument
///    cluster, 0x21 body controller, 0x3D exhaust after-treatment, 0xF9 service tool);
///  - 24 periodic parameter groups at the rates of J1939-71 (10 ms ETC1 and TSC1, 20 ms EEC1,
///    50 ms, 100 ms, 500 ms, 1 s...), each with its own phase, its sender's clock drift
///    (±200 ppm), a release jitter (σ = 0.5 % of the period + 50 us) and, one frame in 100, a
///    late frame (0.2-2 ms: arbitration lost to a burst);
///  - requests and answers: every 2 s the service tool requests engine hours (PGN 0xEA00 to
///    0x00), answered 3-15 ms later; every 5 s the cluster requests component identification from
///    all, answered by the engine and the transmission with a broadcast transport session (TP.CM
///    BAM, then 3 TP.DT 50 ms apart);
///  - payloads that move like signals (counters, slow ramps, "not available" 0xFF bytes).
/// 90 s of it: about 36,000 frames.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace vigil::bench {

namespace detail {

/// splitmix64: a tiny generator whose output does not depend on the standard library.
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }
  /// Uniform in [0, 1).
  double uniform() { return static_cast<double>(next() >> 11U) * 0x1.0p-53; }
  /// Standard normal (Box-Muller).
  double normal() {
    const double u1 = std::max(uniform(), 1e-12);
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  std::uint64_t state_;
};

struct SyntheticFrame {
  std::int64_t t_ns;
  std::uint32_t id;
  std::uint8_t length;
  std::array<std::uint8_t, 8> data;
};

/// J1939 identifier: priority (3 bits), PGN (18 bits), source address.
constexpr std::uint32_t j1939_id(std::uint32_t priority, std::uint32_t pgn, std::uint32_t sa) {
  return (priority << 26U) | (pgn << 8U) | sa;
}

}  // namespace detail

/// What was generated.
struct SyntheticCanLog {
  std::size_t frames = 0;
  std::size_t ids = 0;
  double seconds = 0;
};

/// Writes the capture to `path` (replacing it). Returns what it wrote, or frames == 0 when the
/// file cannot be written.
inline SyntheticCanLog write_synthetic_j1939_log(const std::filesystem::path& path,
                                                 double seconds = 90.0) {
  using detail::j1939_id;
  using detail::SyntheticFrame;
  struct Periodic {
    std::uint32_t id;
    double period_ms;
  };
  // Rates of J1939-71 (and of the real truck capture this replaces).
  const std::vector<Periodic> periodic{
      {j1939_id(3, 0x0F004, 0x00), 20},    // EEC1 engine speed, torque
      {j1939_id(3, 0x0F003, 0x00), 50},    // EEC2 accelerator pedal
      {j1939_id(3, 0x0F002, 0x03), 10},    // ETC1 transmission
      {j1939_id(6, 0x0F005, 0x03), 100},   // ETC2 selected gear
      {j1939_id(3, 0x00000, 0x0B), 10},    // TSC1 brakes -> engine torque request (DA 0x00)
      {j1939_id(6, 0x0F001, 0x0B), 100},   // EBC1 brake controller
      {j1939_id(6, 0x0FEBF, 0x0B), 100},   // EBC2 wheel speeds
      {j1939_id(6, 0x0FEF1, 0x00), 100},   // CCVS engine
      {j1939_id(6, 0x0FEF1, 0x21), 100},   // CCVS body controller
      {j1939_id(6, 0x0FEF2, 0x00), 100},   // LFE fuel economy
      {j1939_id(6, 0x0F00E, 0x3D), 50},    // after-treatment intake NOx
      {j1939_id(6, 0x0F00F, 0x3D), 50},    // after-treatment outlet NOx
      {j1939_id(7, 0x0FE92, 0x00), 500},   // engine information
      {j1939_id(6, 0x0FEEF, 0x00), 500},   // EFL/P1 oil pressure
      {j1939_id(6, 0x0FEF6, 0x00), 500},   // IC1 inlet/exhaust
      {j1939_id(6, 0x0FEFA, 0x21), 500},   // brakes (body controller)
      {j1939_id(6, 0x0FEEE, 0x00), 1000},  // ET1 engine temperature
      {j1939_id(6, 0x0FEF5, 0x00), 1000},  // AMB ambient conditions
      {j1939_id(6, 0x0FEF7, 0x00), 1000},  // VEP vehicle electrical power
      {j1939_id(6, 0x0FEFC, 0x17), 1000},  // DD dash display
      {j1939_id(6, 0x0FEE6, 0x17), 1000},  // TD time/date
      {j1939_id(6, 0x0FECA, 0x00), 1000},  // DM1 engine active diagnostics
      {j1939_id(6, 0x0FECA, 0x03), 1000},  // DM1 transmission
      {j1939_id(6, 0x0FECA, 0x0B), 1000},  // DM1 brakes
  };
  detail::Random rnd(0x5EED'1939ULL);
  const auto end_ns = static_cast<std::int64_t>(seconds * 1e9);
  std::vector<SyntheticFrame> frames;
  frames.reserve(static_cast<std::size_t>(seconds * 420));

  auto payload = [&](std::uint32_t id, std::uint64_t n) {
    std::array<std::uint8_t, 8> d{};
    const double t = static_cast<double>(n);
    d[0] = static_cast<std::uint8_t>(n & 0x0FU);                                   // counter
    d[1] = static_cast<std::uint8_t>(125 + 100 * std::sin(t * 0.013 + id % 7));    // slow ramp
    d[2] = static_cast<std::uint8_t>(rnd.next() & 0x3FU);                          // noise
    d[3] = static_cast<std::uint8_t>(0x80 + 40 * std::sin(t * 0.0021 + id % 11));  // ramp
    d[4] = static_cast<std::uint8_t>(id & 0xFFU);
    d[5] = 0xFF;  // not available
    d[6] = static_cast<std::uint8_t>((id >> 8U) & 0xFFU);
    d[7] = static_cast<std::uint8_t>(n % 3 == 0 ? 0xFF : 0xF0);
    return d;
  };

  for (const auto& p : periodic) {
    const double period_ns = p.period_ms * 1e6 * (1.0 + (rnd.uniform() - 0.5) * 4e-4);  // drift
    const double sigma = 0.005 * p.period_ms * 1e6 + 50e3;
    double nominal = rnd.uniform() * period_ns;  // phase
    for (std::uint64_t n = 0; nominal < static_cast<double>(end_ns); ++n, nominal += period_ns) {
      double t = nominal + std::clamp(rnd.normal(), -3.0, 3.0) * sigma;
      if (rnd.uniform() < 0.01) t += 0.2e6 + rnd.uniform() * 1.8e6;  // late: lost arbitration
      if (t < 0) t = 0;
      frames.push_back({static_cast<std::int64_t>(t), p.id, 8, payload(p.id, n)});
    }
  }
  // Requests and answers.
  for (std::int64_t t = 700'000'000; t < end_ns; t += 2'000'000'000) {  // engine hours
    const auto jitter = static_cast<std::int64_t>(rnd.uniform() * 2e6);
    frames.push_back({t + jitter, j1939_id(6, 0x0EA00, 0xF9), 3, {0xE5, 0xFE, 0x00}});
    const auto answer = t + jitter + 3'000'000 + static_cast<std::int64_t>(rnd.uniform() * 12e6);
    frames.push_back({answer, j1939_id(6, 0x0FEE5, 0x00), 8, payload(0xFEE5, 0)});
  }
  for (std::int64_t t = 1'300'000'000; t < end_ns; t += 5'000'000'000) {  // component id, BAM
    frames.push_back({t, j1939_id(6, 0x0EAFF, 0x17), 3, {0xEB, 0xFE, 0x00}});
    for (const std::uint32_t sa : {0x00U, 0x03U}) {
      auto at = t + 5'000'000 + static_cast<std::int64_t>(rnd.uniform() * 20e6) +
                (sa == 0x03U ? 200'000'000 : 0);
      frames.push_back(
          {at, j1939_id(7, 0x0ECFF, sa), 8, {0x20, 20, 0, 3, 0xFF, 0xEB, 0xFE, 0x00}});  // TP.CM
      for (std::uint8_t k = 1; k <= 3; ++k) {
        at += 50'000'000 + static_cast<std::int64_t>(rnd.normal() * 1e6);
        auto d = payload(0xFEEB, k);
        d[0] = k;
        frames.push_back({at, j1939_id(7, 0x0EBFF, sa), 8, d});  // TP.DT
      }
    }
  }
  std::stable_sort(frames.begin(), frames.end(), [](const auto& a, const auto& b) {
    return a.t_ns != b.t_ns ? a.t_ns < b.t_ns : a.id < b.id;
  });

  SyntheticCanLog out;
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return out;
  constexpr std::int64_t kEpochSeconds = 1'700'000'000;  // a fixed date: the file is reproducible
  std::vector<std::uint32_t> ids;
  for (const auto& fr : frames) {
    const std::int64_t us = fr.t_ns / 1000;
    std::fprintf(f, "(%lld.%06lld) can0 %08X#",
                 static_cast<long long>(kEpochSeconds + us / 1'000'000),
                 static_cast<long long>(us % 1'000'000), fr.id);
    for (std::uint8_t i = 0; i < fr.length; ++i) std::fprintf(f, "%02X", fr.data[i]);
    std::fputc('\n', f);
    ids.push_back(fr.id);
  }
  const bool ok = std::fclose(f) == 0;
  std::sort(ids.begin(), ids.end());
  if (!ok) return out;
  out.frames = frames.size();
  out.ids = static_cast<std::size_t>(std::unique(ids.begin(), ids.end()) - ids.begin());
  out.seconds = seconds;
  return out;
}

}  // namespace vigil::bench
