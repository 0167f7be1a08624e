#include "vigil/monitor/checks/overrun.hpp"

#include <fmt/format.h>

#include "monitor/checks/common.hpp"

namespace vigil::monitor::checks {

void OverrunCheck::run(const CheckInput& in, Report& out) const {
  const OverrunThresholds& t = in.thresholds.overrun;
  const supervisor::ComponentSnapshot& c = in.component;
  const Nanos period = c.has_info ? c.info.period_ns : 0;
  if (!t.enabled || period <= 0) return;
  const double p = static_cast<double>(period);

  if (c.total_ns.count > 0) {
    const double load = c.total_ns.ewma / p;
    out.add("load_ewma", detail::percent(load) + " of period");
    if (t.near_fraction > 0.0 && c.total_ns.ewma > t.near_fraction * p) {
      out.merge(StatusLevel::Warn,
                fmt::format("near overrun: EWMA of total time {} is {} of the {} period (limit {})",
                            format_nanos(c.total_ns.ewma), detail::percent(load), format_nanos(p),
                            detail::percent(t.near_fraction)));
    }
  }

  const Window& w = in.window;
  if (w.cycles == 0) return;
  const double rate = w.overrun_rate();
  out.add("overrun_rate", detail::percent(rate));
  StatusLevel level = StatusLevel::Ok;
  double limit = 0.0;
  if (rate > t.error_rate) {
    level = StatusLevel::Error;
    limit = t.error_rate;
  } else if (rate > t.warn_rate) {
    level = StatusLevel::Warn;
    limit = t.warn_rate;
  }
  if (level == StatusLevel::Ok) return;
  std::string msg = fmt::format("overruns: {} in {} cycles ({}, {} above {})", w.overruns, w.cycles,
                                detail::percent(rate), to_string(level), detail::percent(limit));
  if (w.missed_cycles > 0) msg += fmt::format(", {} cycles missed", w.missed_cycles);
  out.merge(level, std::move(msg));
}

}  // namespace vigil::monitor::checks
