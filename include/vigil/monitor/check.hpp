#pragma once
/// @file
/// Checks: what the monitor runs on every component each cycle. A check reads one component's
/// snapshot and thresholds, adds key/values to its report and merges a status into it.
///
/// A custom check is one class and one registration line:
///
/// ```cpp
/// struct LatencyCheck {                                   // satisfies vigil::Check
///   std::string_view name() const { return "latency"; }
///   void run(const vigil::CheckInput& in, vigil::Report& out) {
///     const double limit = in.thresholds.custom_value("latency_p99_us", 200) * 1e3;
///     if (in.component.latency_ns.p99 > limit) out.merge(vigil::StatusLevel::Warn, "late
///     wake-ups");
///   }
/// };
/// monitor.add_check<LatencyCheck>();                      // the registration line
/// ```
///
/// Checks run on the monitor thread only (never concurrently with themselves), so a check may
/// keep state in its members. An exception thrown by a check is caught by the monitor and turns
/// the component's status to Error "check <name> failed: <what>". Not RT-safe.

#include <concepts>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "vigil/monitor/report.hpp"
#include "vigil/monitor/thresholds.hpp"
#include "vigil/supervisor/component_aggregator.hpp"

namespace vigil::monitor {

/// What a check sees about one component in one monitor cycle. References are valid during the
/// call only.
struct CheckInput {
  const supervisor::ComponentSnapshot& component;  ///< the aggregator's record of the component
  const Thresholds& thresholds;                    ///< the component's (defaults + its overrides)
  const Window& window;                            ///< counter deltas over the recent window
  Nanos now_ns;                                    ///< monitor clock at the start of the cycle
  /// Time since the latest cycle arrived, or since the monitor saw the component enter Running if
  /// later; -1 when the component is not Running (or left).
  Nanos silence_ns;
};

/**
 * A check: `name()` names it in messages and logs; `run(in, out)` adds key/values to `out` with
 * `out.add(key, value)` and merges findings with `out.merge(level, message)`.
 * `out` already holds the component's identity, counters and statistics, and what the checks
 * before this one added.
 */
template <class C>
concept Check = requires(C& c, const C& cc, const CheckInput& in, Report& out) {
  { cc.name() } -> std::convertible_to<std::string_view>;
  { c.run(in, out) } -> std::same_as<void>;
};

/// The runtime form of a check, for lists of checks of different types. Derive from it directly,
/// or write a plain class satisfying `Check` and let `CheckList::add` wrap it.
class CheckBase {
 public:
  virtual ~CheckBase() = default;
  [[nodiscard]] virtual std::string_view name() const = 0;
  virtual void run(const CheckInput& in, Report& out) = 0;
};

namespace detail {
template <Check C>
class CheckAdapter final : public CheckBase {
 public:
  template <class... A>
  explicit CheckAdapter(A&&... args) : check_(std::forward<A>(args)...) {}
  [[nodiscard]] std::string_view name() const override { return check_.name(); }
  void run(const CheckInput& in, Report& out) override { check_.run(in, out); }
  [[nodiscard]] C& get() noexcept { return check_; }

 private:
  C check_;
};
}  // namespace detail

/// An ordered list of checks, run one after the other on each component. Not thread-safe (the
/// Monitor serialises access); not RT-safe.
class CheckList {
 public:
  CheckList() = default;
  CheckList(CheckList&&) noexcept = default;
  CheckList& operator=(CheckList&&) noexcept = default;

  /// Appends a check of type `C` built from `args`. Returns it (owned by the list).
  template <Check C, class... A>
  C& add(A&&... args) {
    return emplace_<C>(std::forward<A>(args)...);
  }
  /// Appends `check` (moved in). Returns it (owned by the list).
  template <Check C>
  C& add(C check) {
    return emplace_<C>(std::move(check));
  }
  /// Appends an already built runtime check. Null is ignored.
  void add(std::unique_ptr<CheckBase> check) {
    if (check) checks_.push_back(std::move(check));
  }
  /// Removes every check named `name`; returns how many.
  std::size_t remove(std::string_view name);

  /// Runs every check on one component, in order; an exception from a check is caught and
  /// merged as Error "check <name> failed: <what>".
  void run(const CheckInput& in, Report& out) const;

  [[nodiscard]] std::size_t size() const noexcept { return checks_.size(); }
  [[nodiscard]] bool empty() const noexcept { return checks_.empty(); }
  /// The names of the checks, in order.
  [[nodiscard]] std::vector<std::string> names() const;

 private:
  template <class C, class... A>
  C& emplace_(A&&... args) {
    if constexpr (std::is_base_of_v<CheckBase, C>) {
      auto p = std::make_unique<C>(std::forward<A>(args)...);
      C& ref = *p;
      checks_.push_back(std::move(p));
      return ref;
    } else {
      auto p = std::make_unique<detail::CheckAdapter<C>>(std::forward<A>(args)...);
      C& ref = p->get();
      checks_.push_back(std::move(p));
      return ref;
    }
  }

  std::vector<std::unique_ptr<CheckBase>> checks_;
};

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::Check;
using monitor::CheckBase;
using monitor::CheckInput;
}  // namespace vigil
