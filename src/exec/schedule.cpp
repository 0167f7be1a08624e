#include "vigil/exec/schedule.hpp"

namespace vigil::exec {

Schedule::Schedule(Nanos period_ns, OverrunPolicy policy, OverrunLimit limit)
    : period_(period_ns), policy_(policy), limit_(limit) {
  if (limit_.max_overruns > 0 && limit_.window_cycles > 0) {
    window_.assign((limit_.window_cycles + 63) / 64, 0);
    limited_ = true;
  }
}

Schedule::Outcome Schedule::advance_slow(Nanos end) noexcept {
  Outcome o;
  const Nanos deadline = release_ + period_;
  o.overrun = period_ > 0 && end > deadline;
  if (!o.overrun) {
    release_ = deadline;
  } else {
    ++overruns_;
    // Releases strictly before `end` after the current one: release_+P ... <= end - 1.
    const auto passed = static_cast<std::uint64_t>((end - release_ - 1) / period_);
    switch (policy_) {
      case OverrunPolicy::CatchUp:
        release_ = deadline;
        break;
      case OverrunPolicy::Skip:
        release_ += static_cast<Nanos>(passed) * period_;
        if (release_ < end) release_ += period_;
        o.missed = static_cast<std::uint32_t>((release_ - deadline) / period_);
        break;
      case OverrunPolicy::Reanchor:
        o.missed = static_cast<std::uint32_t>(passed);
        release_ = end + period_;
        break;
    }
    missed_ += o.missed;
  }
  if (!window_.empty()) {
    const std::uint64_t bit = cycle_ % limit_.window_cycles;
    auto& word = window_[bit / 64];
    const std::uint64_t mask = std::uint64_t{1} << (bit % 64);
    if ((word & mask) != 0) --in_window_;
    if (o.overrun) {
      word |= mask;
      ++in_window_;
    } else {
      word &= ~mask;
    }
    o.limit_reached = in_window_ >= limit_.max_overruns;
  }
  ++cycle_;
  return o;
}

}  // namespace vigil::exec
