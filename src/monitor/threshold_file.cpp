#include "vigil/monitor/threshold_file.hpp"

#include <mutex>
#include <utility>

#include "vigil/monitor/monitor.hpp"

namespace vigil::monitor {

struct ThresholdFile::State {
  explicit State(config::Reloadable<ThresholdSet> f) : file(std::move(f)) {}

  // Gives the monitor the outcome of the last attempt (lock held).
  void apply(bool ok) {
    if (monitor == nullptr) return;
    if (ok) {
      monitor->set_thresholds(file.current(), file.generation());
    } else {
      monitor->set_threshold_errors(file.last_errors());
    }
  }

  config::ReloadStatus poll() {
    std::lock_guard lock(mutex);
    const config::ReloadStatus s = file.poll();
    if (s != config::ReloadStatus::Unchanged) apply(s == config::ReloadStatus::Reloaded);
    return s;
  }

  config::Reloadable<ThresholdSet> file;
  // Serialises attempts with their hand-over to the monitor, so that the monitor always ends with
  // the outcome of the latest attempt. Lock order: this mutex, then the monitor's own; never
  // held while the monitor's hooks are changed (that waits for a cycle, which may poll).
  std::mutex mutex;
  Monitor* monitor = nullptr;
  std::uint64_t hook = 0;
};

ThresholdFile::ThresholdFile(std::shared_ptr<State> state) noexcept : state_(std::move(state)) {}
ThresholdFile::ThresholdFile(ThresholdFile&&) noexcept = default;
ThresholdFile& ThresholdFile::operator=(ThresholdFile&& other) noexcept {
  if (this != &other) {
    detach();
    state_ = std::move(other.state_);
  }
  return *this;
}
ThresholdFile::~ThresholdFile() { detach(); }

expected<ThresholdFile, config::ConfigErrors> ThresholdFile::open(
    const std::filesystem::path& path) {
  auto file = config::Reloadable<ThresholdSet>::open(
      path, [](const config::Node& root) { return load_thresholds(root); });
  if (!file) return vigil::unexpected<config::ConfigErrors>(std::move(file.error()));
  return ThresholdFile(std::make_shared<State>(std::move(*file)));
}

void ThresholdFile::attach(Monitor& monitor, bool poll_each_cycle) {
  detach();
  {
    std::lock_guard lock(state_->mutex);
    state_->monitor = &monitor;
    state_->apply(true);
  }
  if (!poll_each_cycle) return;
  // The hook owns a reference to the state: it stays valid however long a cycle runs it.
  const std::uint64_t id = monitor.add_cycle_hook([s = state_] { s->poll(); });
  std::lock_guard lock(state_->mutex);
  state_->hook = id;
}

void ThresholdFile::detach() {
  if (!state_) return;  // moved from
  Monitor* monitor = nullptr;
  std::uint64_t hook = 0;
  {
    std::lock_guard lock(state_->mutex);
    monitor = std::exchange(state_->monitor, nullptr);
    hook = std::exchange(state_->hook, 0);
  }
  if (monitor != nullptr && hook != 0) monitor->remove_cycle_hook(hook);
}

expected<std::uint64_t, config::ConfigErrors> ThresholdFile::reload() {
  std::lock_guard lock(state_->mutex);
  auto r = state_->file.reload();
  state_->apply(r.has_value());
  return r;
}

config::ReloadStatus ThresholdFile::poll() { return state_->poll(); }

std::shared_ptr<const ThresholdSet> ThresholdFile::current() const {
  return state_->file.current();
}
std::uint64_t ThresholdFile::generation() const { return state_->file.generation(); }
config::ConfigErrors ThresholdFile::errors() const { return state_->file.last_errors(); }
const std::filesystem::path& ThresholdFile::path() const { return state_->file.path(); }

}  // namespace vigil::monitor
