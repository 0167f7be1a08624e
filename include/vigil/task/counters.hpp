#pragma once
/// @file
/// `Counters`: the cumulative counters of a component, the one type used everywhere they appear
/// (each CycleSample carries them, the recorder keeps them on the RT side, the aggregator keeps
/// them per component, the monitor's Window holds their difference over a window).
///
/// Adding a counter touches this file only: declare the member and add it to `kScalars` (the
/// static_assert below fails when a member is missing from the list). `merge`, `since` and
/// `total_losses` walk the list.

#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "vigil/platform/rt_loss.hpp"

namespace vigil::task {

/// Number of real-time-loss causes (platform::LossCause), the size of `Counters::losses`.
inline constexpr int kLossCauses = platform::kLossCauseCount;

/// Cumulative counters since the component joined, exact even when samples were dropped.
/// Trivially copyable (it travels in every CycleSample); every member function is RT-safe.
struct Counters {
  std::uint64_t cycles = 0;                         ///< cycles run (the number of the latest cycle)
  std::uint64_t overruns = 0;                       ///< cycles that ended after their next release
  std::uint64_t missed_cycles = 0;                  ///< releases skipped (Skip / Reanchor policies)
  std::array<std::uint64_t, kLossCauses> losses{};  ///< real-time losses, by LossCause
  std::uint64_t exceptions = 0;                     ///< exceptions caught at hook boundaries
  std::uint64_t dropped = 0;                        ///< messages its port dropped

  /// Every scalar counter (losses apart): what merge() and since() walk.
  static constexpr std::array kScalars{&Counters::cycles, &Counters::overruns,
                                       &Counters::missed_cycles, &Counters::exceptions,
                                       &Counters::dropped};

  /// Keeps the larger of each counter. Counters only grow, so the larger value is the newer one:
  /// merging reports that arrive late or twice (a totals-only sample, an exception report) never
  /// moves a counter back.
  constexpr void merge(const Counters& o) noexcept {
    for (auto m : kScalars) this->*m = this->*m >= o.*m ? this->*m : o.*m;
    for (std::size_t i = 0; i < losses.size(); ++i) {
      losses[i] = losses[i] >= o.losses[i] ? losses[i] : o.losses[i];
    }
  }

  /// What was counted since `earlier` (this - earlier, per counter). A counter below its earlier
  /// value (a component that restarted under the same record) counts 0, never wraps.
  [[nodiscard]] constexpr Counters since(const Counters& earlier) const noexcept {
    Counters d;
    for (auto m : kScalars) d.*m = this->*m >= earlier.*m ? this->*m - earlier.*m : 0;
    for (std::size_t i = 0; i < losses.size(); ++i) {
      d.losses[i] = losses[i] >= earlier.losses[i] ? losses[i] - earlier.losses[i] : 0;
    }
    return d;
  }

  /// Real-time losses of every cause.
  [[nodiscard]] constexpr std::uint64_t total_losses() const noexcept {
    std::uint64_t n = 0;
    for (auto v : losses) n += v;
    return n;
  }
  /// The losses of one cause.
  [[nodiscard]] constexpr std::uint64_t loss(platform::LossCause c) const noexcept {
    return losses[static_cast<std::size_t>(c)];
  }

  friend constexpr bool operator==(const Counters&, const Counters&) = default;
};

static_assert(std::is_trivially_copyable_v<Counters>, "Counters travel in every CycleSample");
static_assert(sizeof(Counters) == (Counters::kScalars.size() + kLossCauses) * sizeof(std::uint64_t),
              "a member of Counters is missing from Counters::kScalars");

}  // namespace vigil::task
