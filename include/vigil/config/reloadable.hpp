#pragma once
/// @file
/// `Reloadable<T>`: a configuration value loaded from a file and reloaded at run time, where a
/// bad reload keeps the previous value.
///
/// Design: a non-template core (`detail::ReloadableCore`, compiled once) owns the path, a
/// type-erased loader, the current value as `shared_ptr<const void>`, the generation counter,
/// the errors of the last attempt and the subscribers; `Reloadable<T>` is a thin typed handle.
/// Readers copy a `shared_ptr<const T>` under a mutex held only for that copy, so a reader never
/// waits for file I/O or a loader, and a value stays alive as long as someone holds it. Reloads
/// are serialised by a second mutex that readers never take.
///
/// Nothing here is RT-safe: readers are non-real-time threads (supervisor, monitor, exporters);
/// the real-time side never reads configuration.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <type_traits>
#include <utility>
#include <vector>

#include "vigil/config/error.hpp"
#include "vigil/config/load.hpp"
#include "vigil/config/node.hpp"
#include "vigil/expected.hpp"

namespace vigil::config {

class FileWatcher;

/// What `poll()` did.
enum class ReloadStatus : std::uint8_t {
  Unchanged,  ///< The file's modification time and size are those of the last attempt.
  Reloaded,   ///< The file changed and the new value is now current.
  Failed,     ///< The file changed but did not load; the previous value is still current.
};

namespace detail {

/// The type-erased state behind `Reloadable<T>` (see the file comment). Thread-safe.
class ReloadableCore {
 public:
  using Value = std::shared_ptr<const void>;
  using ErasedLoader = std::function<expected<Value, ConfigErrors>(const Node&)>;
  using ErasedCallback = std::function<void(const Value&, std::uint64_t)>;

  ReloadableCore(std::filesystem::path path, ErasedLoader loader);
  ReloadableCore(const ReloadableCore&) = delete;
  ReloadableCore& operator=(const ReloadableCore&) = delete;

  expected<std::uint64_t, ConfigErrors> reload();
  ReloadStatus poll();
  [[nodiscard]] Value current() const;
  [[nodiscard]] std::uint64_t generation() const noexcept;
  [[nodiscard]] ConfigErrors last_errors() const;
  std::uint64_t subscribe(ErasedCallback callback);
  void unsubscribe(std::uint64_t id);
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }

 private:
  // What poll() compares. A file that cannot be stat'ed has exists == false.
  struct Stamp {
    bool exists = false;
    std::filesystem::file_time_type mtime{};
    std::uintmax_t size = 0;
    friend bool operator==(const Stamp&, const Stamp&) = default;
  };
  [[nodiscard]] Stamp stamp_now_() const;
  expected<std::uint64_t, ConfigErrors> reload_locked_(const Stamp& stamp);
  void notify_(const Value& value, std::uint64_t generation) noexcept;

  const std::filesystem::path path_;
  const ErasedLoader loader_;

  std::mutex reload_mutex_;  // serialises reload() and poll(); readers never take it
  Stamp stamp_;              // of the last attempt; guarded by reload_mutex_

  mutable std::mutex value_mutex_;  // guards value_ and last_errors_; held only to copy them
  Value value_;
  ConfigErrors last_errors_;
  std::atomic<std::uint64_t> generation_{0};

  std::mutex subscribers_mutex_;  // guards subscribers_ and next_id_, never held during a call
  std::vector<std::pair<std::uint64_t, ErasedCallback>> subscribers_;
  std::uint64_t next_id_ = 1;
};

}  // namespace detail

/**
 * A value of type `T` loaded from a YAML file by a schema loader and reloaded on request.
 *
 * `open()` loads the file once and fails if that load fails, so `current()` is never null.
 * `reload()` re-reads the file: on success it publishes the new value and increments
 * `generation()`; on failure it keeps the previous value and returns (and stores, see
 * `last_errors()`) every error. `poll()` reloads only when the file's modification time or size
 * changed since the last attempt, for a `FileWatcher` or the monitor's own cycle to call.
 *
 * Copies are handles on the same state. All members are thread-safe. None is RT-safe.
 *
 * **Example**:
 * ```
 * auto limits = config::Reloadable<Limits>::open("limits.yaml", load_limits);
 * if (!limits) { fmt::print(stderr, "{}\n", config::to_string(limits.error())); return 1; }
 * std::shared_ptr<const Limits> now = limits->current();   // any non-RT thread
 * if (limits->poll() == config::ReloadStatus::Failed)
 *   log_errors(limits->last_errors());                       // previous value still in use
 * ```
 */
template <class T>
class Reloadable {
 public:
  /// Loads `path` with `loader` (returning `T` or `expected<T, ConfigErrors>`, see `Loader`).
  /// Fails with every error of the first load. `loader` is kept for reloads and is never called
  /// by two threads at once.
  template <Loader F>
  [[nodiscard]] static expected<Reloadable, ConfigErrors> open(std::filesystem::path path,
                                                               F loader) {
    static_assert(std::is_same_v<detail::Loaded<F>, T>,
                  "Reloadable<T>::open: the loader must return T or expected<T, ConfigErrors>");
    auto core = std::make_shared<detail::ReloadableCore>(
        std::move(path),
        [f = std::move(loader)](
            const Node& root) mutable -> expected<detail::ReloadableCore::Value, ConfigErrors> {
          expected<T, ConfigErrors> r = detail::run_loader(root, f);
          if (!r.has_value()) return vigil::unexpected<ConfigErrors>(std::move(r.error()));
          return std::shared_ptr<const T>(std::make_shared<const T>(std::move(*r)));
        });
    expected<std::uint64_t, ConfigErrors> first = core->reload();
    if (!first.has_value()) return vigil::unexpected<ConfigErrors>(std::move(first.error()));
    return Reloadable(std::move(core));
  }

  /// The current value; never null. Takes a mutex for the time of one shared_ptr copy.
  [[nodiscard]] std::shared_ptr<const T> current() const {
    return std::static_pointer_cast<const T>(core_->current());
  }

  /// 1 after `open()`, incremented by every successful reload. Lock-free.
  [[nodiscard]] std::uint64_t generation() const noexcept { return core_->generation(); }

  /// Re-reads the file now. Returns the new generation, or every error (the previous value stays
  /// current). Waits for a reload or poll running in another thread. Subscribers are called on
  /// this thread before it returns.
  expected<std::uint64_t, ConfigErrors> reload() { return core_->reload(); }

  /// Reloads if the file's modification time or size changed since the last attempt
  /// (successful or not), so a bad file is reported once, not at every poll. A file that
  /// disappears counts as a change and fails to load. Changes that keep both the time stamp and
  /// the size are missed (write the file again, or touch it).
  ReloadStatus poll() { return core_->poll(); }

  /// The errors of the last attempt, empty when it succeeded.
  [[nodiscard]] ConfigErrors last_errors() const { return core_->last_errors(); }

  /// Calls `callback(const std::shared_ptr<const T>& value, std::uint64_t generation)` after
  /// every successful reload (not for the value of `open()`), on the reloading thread, once the
  /// new value is current. It runs outside the readers' lock but inside the reload lock: it may
  /// call `current()`, `subscribe()` or `unsubscribe()`, not `reload()`/`poll()` on the same
  /// object (that would deadlock). It must not throw (std::terminate). Returns an id for
  /// `unsubscribe`.
  template <class F>
  requires std::invocable < F&, const std::shared_ptr<const T>
  &, std::uint64_t > std::uint64_t subscribe(F callback) {
    return core_->subscribe([cb = std::move(callback)](const detail::ReloadableCore::Value& v,
                                                       std::uint64_t generation) mutable {
      cb(std::static_pointer_cast<const T>(v), generation);
    });
  }

  /// Removes a subscription; unknown ids are ignored. A call already under way may still finish.
  void unsubscribe(std::uint64_t id) { core_->unsubscribe(id); }

  /// The file this value is loaded from.
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return core_->path(); }

 private:
  friend class FileWatcher;
  explicit Reloadable(std::shared_ptr<detail::ReloadableCore> core) : core_(std::move(core)) {}

  std::shared_ptr<detail::ReloadableCore> core_;
};

}  // namespace vigil::config
