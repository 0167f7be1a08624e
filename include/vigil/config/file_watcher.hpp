#pragma once
/// @file
/// `FileWatcher`: a thread that polls `Reloadable` configurations at a fixed period.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "vigil/config/reloadable.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/thread.hpp"

namespace vigil::config {

/**
 * Polls every watched `Reloadable` once per period on its own (non-real-time) thread, so that
 * edited files take effect without a restart and bad edits are reported once and ignored.
 *
 * The thread starts in the constructor and stops in `stop()` or the destructor, which wake it at
 * once (no wait for the period to end) and join it. Watching keeps the configuration's state
 * alive. All members are thread-safe; none is RT-safe. Errors are not reported here: read
 * `last_errors()`, or subscribe, on the configuration.
 *
 * **Example**:
 * ```
 * config::FileWatcher watcher(250 * kNanosPerMilli);
 * watcher.watch(limits);   // a Reloadable<Limits>
 * ```
 */
class FileWatcher {
 public:
  /// Starts the polling thread (named "vigil-watcher", SCHED_OTHER, a stack of `stack_bytes`;
  /// 0 keeps the system default); `period_ns` is the time between two rounds (at least 1 ms is
  /// sensible: each round stats every file). A reload (parsing and validating the file, and the
  /// subscribers) runs on this thread. Throws std::system_error if the thread cannot be created.
  explicit FileWatcher(Nanos period_ns = 250 * kNanosPerMilli,
                       std::size_t stack_bytes = platform::kDefaultStackBytes);
  /// Stops and joins the thread.
  ~FileWatcher();
  FileWatcher(const FileWatcher&) = delete;
  FileWatcher& operator=(const FileWatcher&) = delete;

  /// Adds `config` to the configurations polled each round (from the next round on).
  template <class T>
  void watch(const Reloadable<T>& config) {
    add_(config.core_);
  }

  /// Stops polling and joins the thread; idempotent, and safe to call from several threads. A
  /// round under way finishes first. Must not be called from a reload subscriber (the watcher's
  /// own thread cannot join itself).
  void stop() noexcept;

  /// Number of rounds completed so far (each round polls every watched configuration).
  [[nodiscard]] std::uint64_t rounds() const noexcept;

 private:
  void add_(std::shared_ptr<detail::ReloadableCore> core);
  void run_();

  const Nanos period_ns_;
  mutable std::mutex mutex_;  // guards watched_ and stop_
  std::condition_variable wake_;
  std::vector<std::shared_ptr<detail::ReloadableCore>> watched_;
  bool stop_ = false;
  std::once_flag joined_;
  std::atomic<std::uint64_t> rounds_{0};
  platform::Thread thread_;  // last: started once every other member exists
};

}  // namespace vigil::config
