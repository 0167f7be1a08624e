#include "vigil/log/service.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <deque>
#include <exception>
#include <stdexcept>

#include "vigil/log/source.hpp"

namespace vigil::log {

struct LogService::Component {
  std::string name;
  std::deque<Line> recent;
  ComponentLogStats stats;
};

LogService::LogService(LogServiceOptions options) : options_(options) {}

LogService::~LogService() {
  try {
    flush();
  } catch (...) {  // a destructor does not throw; the pending counts are lost
  }
}

void LogService::add_sink(std::shared_ptr<Sink> sink) {
  if (!sink) return;
  std::lock_guard lock(mutex_);
  sinks_.push_back(std::move(sink));
}

LogService::Component& LogService::component(std::string_view name) {
  auto it = components_.find(name);
  if (it == components_.end()) {
    auto c = std::make_unique<Component>();
    c->name = std::string(name);
    it = components_.emplace(c->name, std::move(c)).first;
  }
  return *it->second;
}

void LogService::write(Component& c, Line line) {
  for (const auto& s : sinks_) s->write(line);
  wrote_ = true;
  if (options_.recent == 0) return;
  if (c.recent.size() == options_.recent) c.recent.pop_front();
  c.recent.push_back(std::move(line));
}

void LogService::close_window(const RateKey& key, Rate& r) {
  if (r.suppressed > 0) {
    Line l;
    l.component = r.component->name;
    l.level = key.site->level;
    l.cycle = r.last_cycle;
    l.time_ns = r.last_time_ns;
    l.text = fmt::format("... {} line{} suppressed (rate limit {}/s)", r.suppressed,
                         r.suppressed == 1 ? "" : "s", options_.rate_limit);
    l.file = key.site->file;
    l.line = key.site->line;
    l.suppressed = r.suppressed;
    write(*r.component, std::move(l));
    --pending_;
  }
  r.open = false;
  r.count = 0;
  r.suppressed = 0;
}

void LogService::on_record(std::uint32_t id, std::string_view name, const LogRecord& record) {
  std::lock_guard lock(mutex_);
  Component& c = component(name);

  // Drops: each record carries the count of its component's records dropped before it.
  std::uint32_t& seen = seen_dropped_[id];
  const std::uint32_t lost = record.dropped - seen;  // modulo 2^32, as the counter wraps
  if (lost != 0) {
    seen = record.dropped;
    c.stats.dropped += lost;
    Line l;
    l.component = c.name;
    l.level = Level::Warn;
    l.cycle = record.cycle;
    l.time_ns = record.time_ns;
    l.text = fmt::format("... {} log record{} dropped (port full)", lost, lost == 1 ? "" : "s");
    l.dropped = lost;
    write(c, std::move(l));
  }

  if (record.site == nullptr) {
    ++format_errors_;
    return;
  }
  const CallSite& site = *record.site;

  if (options_.rate_limit > 0) {
    const RateKey key{id, &site};
    Rate& r = rates_[key];
    if (r.open && record.time_ns - r.window_ns >= kNanosPerSecond) close_window(key, r);
    if (!r.open) {
      r.open = true;
      r.window_ns = record.time_ns;
      r.component = &c;
    }
    if (r.count >= options_.rate_limit) {
      if (r.suppressed++ == 0) ++pending_;
      r.last_cycle = record.cycle;
      r.last_time_ns = record.time_ns;
      ++c.stats.suppressed;
      return;
    }
    ++r.count;
  }

  Line l;
  l.component = c.name;
  l.level = site.level;
  l.cycle = record.cycle;
  l.time_ns = record.time_ns;
  l.file = site.file;
  l.line = site.line;
  try {
    if (site.decode == nullptr) throw std::runtime_error("no decoder");
    site.decode(l.text, site, record);
  } catch (const std::exception& e) {
    ++format_errors_;
    l.text = fmt::format("<format error: {}> {}", e.what(), site.format);
  }
  ++c.stats.lines;
  write(c, std::move(l));
}

void LogService::on_supervisor_cycle(Nanos now) {
  std::lock_guard lock(mutex_);
  if (pending_ > 0) {
    for (auto& [key, r] : rates_) {
      if (r.suppressed > 0 && now - r.window_ns >= kNanosPerSecond) close_window(key, r);
    }
  }
  if (wrote_) {
    for (const auto& s : sinks_) s->flush();
    wrote_ = false;
  }
}

void LogService::flush() {
  std::lock_guard lock(mutex_);
  if (pending_ > 0) {
    for (auto& [key, r] : rates_) {
      if (r.suppressed > 0) close_window(key, r);
    }
  }
  for (const auto& s : sinks_) s->flush();
  wrote_ = false;
}

std::vector<Line> LogService::recent(std::string_view name, std::size_t n) const {
  std::lock_guard lock(mutex_);
  const auto it = components_.find(name);
  if (it == components_.end()) return {};
  const auto& q = it->second->recent;
  const std::size_t k = std::min(n, q.size());
  return {q.end() - static_cast<std::ptrdiff_t>(k), q.end()};
}

ComponentLogStats LogService::stats(std::string_view name) const {
  ComponentLogStats s;
  {
    std::lock_guard lock(mutex_);
    const auto it = components_.find(name);
    if (it != components_.end()) s = it->second->stats;
  }
  // Drops the live component has not reported yet (no record got through since).
  s.dropped = std::max(s.dropped, log::dropped(name));
  return s;
}

std::vector<std::string> LogService::components() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> names;
  names.reserve(components_.size());
  for (const auto& [name, c] : components_) names.push_back(name);
  return names;
}

std::uint64_t LogService::format_errors() const {
  std::lock_guard lock(mutex_);
  return format_errors_;
}

}  // namespace vigil::log
