#include "vigil/config/file_watcher.hpp"

#include <chrono>
#include <system_error>

namespace vigil::config {

FileWatcher::FileWatcher(Nanos period_ns, std::size_t stack_bytes) : period_ns_(period_ns) {
  auto t = platform::Thread::spawn({.name = "vigil-watcher", .stack_bytes = stack_bytes},
                                   [this] { run_(); });
  if (!t) throw std::system_error(t.error().code, std::generic_category(), t.error().message);
  thread_ = std::move(*t);
}

FileWatcher::~FileWatcher() { stop(); }

void FileWatcher::add_(std::shared_ptr<detail::ReloadableCore> core) {
  const std::lock_guard lock(mutex_);
  watched_.push_back(std::move(core));
}

void FileWatcher::stop() noexcept {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  std::call_once(joined_, [this] { thread_.join(); });
}

std::uint64_t FileWatcher::rounds() const noexcept { return rounds_.load(); }

void FileWatcher::run_() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    // Poll outside the lock: a reload may take a while and watch()/stop() must not wait for it.
    const std::vector<std::shared_ptr<detail::ReloadableCore>> watched = watched_;
    lock.unlock();
    for (const auto& core : watched) (void)core->poll();
    rounds_.fetch_add(1);
    lock.lock();
    wake_.wait_for(lock, std::chrono::nanoseconds(period_ns_), [this] { return stop_; });
  }
}

}  // namespace vigil::config
