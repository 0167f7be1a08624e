#include "vigil/monitor/thresholds.hpp"

#include <fmt/format.h>

#include <utility>

#include "vigil/config/load.hpp"
#include "vigil/config/node.hpp"

namespace vigil::monitor {

double Thresholds::custom_value(std::string_view key, double fallback) const {
  const auto it = custom.find(key);
  return it == custom.end() ? fallback : it->second;
}

const Thresholds& ThresholdSet::for_component(std::string_view name) const {
  const auto it = components.find(name);
  return it == components.end() ? defaults : it->second;
}

namespace {

constexpr Nanos kHour = 3600 * kNanosPerSecond;
constexpr Nanos kDay = 24 * kHour;

bool enabled(const config::Node& n, bool fallback) { return n.optional<bool>("enabled", fallback); }

}  // namespace

Thresholds read_thresholds(const config::Node& n, const Thresholds& base) {
  n.reject_unknown_keys({"window", "initialization", "exception", "overrun", "starvation",
                         "realtime", "not_realtime", "overhead", "drops", "custom"});
  Thresholds t = base;
  t.window_ns = n.optional_duration("window", base.window_ns, config::duration_in_range(0, kHour));
  {
    const config::Node s = n["initialization"];
    s.reject_unknown_keys({"enabled"});
    t.initialization.enabled = enabled(s, base.initialization.enabled);
  }
  {
    const config::Node s = n["exception"];
    s.reject_unknown_keys({"enabled", "sticky"});
    t.exception.enabled = enabled(s, base.exception.enabled);
    t.exception.sticky = s.optional<bool>("sticky", base.exception.sticky);
  }
  {
    const config::Node s = n["overrun"];
    s.reject_unknown_keys({"enabled", "near_fraction", "warn_rate", "error_rate"});
    const auto unit = config::in_range(0.0, 1.0);
    t.overrun.enabled = enabled(s, base.overrun.enabled);
    t.overrun.near_fraction = s.optional<double>("near_fraction", base.overrun.near_fraction, unit);
    t.overrun.warn_rate = s.optional<double>("warn_rate", base.overrun.warn_rate, unit);
    t.overrun.error_rate = s.optional<double>("error_rate", base.overrun.error_rate, unit);
    if (t.overrun.error_rate < t.overrun.warn_rate) {
      // Reported at whichever of the two this block sets (the error rate when both).
      if (s.has("error_rate")) {
        s["error_rate"].error(fmt::format("must not be below warn_rate ({}), got '{}'",
                                          t.overrun.warn_rate, t.overrun.error_rate));
      } else {
        s["warn_rate"].error(fmt::format("must not be above error_rate ({}), got '{}'",
                                         t.overrun.error_rate, t.overrun.warn_rate));
      }
    }
  }
  {
    const config::Node s = n["starvation"];
    s.reject_unknown_keys({"enabled", "periods", "min_silence", "aperiodic_silence"});
    t.starvation.enabled = enabled(s, base.starvation.enabled);
    t.starvation.periods =
        s.optional<double>("periods", base.starvation.periods, config::in_range(1.0, 1e6));
    t.starvation.min_silence_ns = s.optional_duration("min_silence", base.starvation.min_silence_ns,
                                                      config::duration_in_range(0, kHour));
    t.starvation.aperiodic_silence_ns =
        s.optional_duration("aperiodic_silence", base.starvation.aperiodic_silence_ns,
                            config::duration_in_range(0, kDay));
  }
  {
    const config::Node s = n["realtime"];
    s.reject_unknown_keys({"enabled", "warn_losses", "fifo_only"});
    t.realtime.enabled = enabled(s, base.realtime.enabled);
    t.realtime.warn_losses = s.optional<std::uint64_t>("warn_losses", base.realtime.warn_losses);
    t.realtime.fifo_only = s.optional<bool>("fifo_only", base.realtime.fifo_only);
  }
  {
    const config::Node s = n["not_realtime"];
    s.reject_unknown_keys({"enabled"});
    t.not_realtime.enabled = enabled(s, base.not_realtime.enabled);
  }
  {
    const config::Node s = n["overhead"];
    s.reject_unknown_keys({"enabled", "warn_share", "min_overhead", "min_period_share"});
    const auto unit = config::in_range(0.0, 1.0);
    t.overhead.enabled = enabled(s, base.overhead.enabled);
    t.overhead.warn_share = s.optional<double>("warn_share", base.overhead.warn_share, unit);
    t.overhead.min_overhead_ns = s.optional_duration("min_overhead", base.overhead.min_overhead_ns,
                                                     config::duration_in_range(0, kNanosPerSecond));
    t.overhead.min_period_share =
        s.optional<double>("min_period_share", base.overhead.min_period_share, unit);
  }
  {
    const config::Node s = n["drops"];
    s.reject_unknown_keys({"enabled", "warn_drops"});
    t.drops.enabled = enabled(s, base.drops.enabled);
    t.drops.warn_drops = s.optional<std::uint64_t>("warn_drops", base.drops.warn_drops);
  }
  for (const auto& [key, value] : n["custom"].entries()) {
    t.custom[key] = value.get<double>();
  }
  return t;
}

expected<ThresholdSet, config::ConfigErrors> load_thresholds(const config::Node& root) {
  root.reject_unknown_keys({"defaults", "components"});
  ThresholdSet set;
  set.source = root.file();
  set.defaults = read_thresholds(root["defaults"], Thresholds{});
  for (const auto& [name, node] : root["components"].entries()) {
    set.components.insert_or_assign(name, read_thresholds(node, set.defaults));
  }
  return root.finish(std::move(set));
}

expected<ThresholdSet, config::ConfigErrors> load_thresholds_file(
    const std::filesystem::path& path) {
  return config::load_file(path, [](const config::Node& root) { return load_thresholds(root); });
}

expected<ThresholdSet, config::ConfigErrors> load_thresholds_string(std::string_view text,
                                                                    std::string name) {
  return config::load_string(text, std::move(name),
                             [](const config::Node& root) { return load_thresholds(root); });
}

}  // namespace vigil::monitor
