#pragma once
/// @file
/// `ThresholdFile`: a thresholds file (docs/reference/thresholds.md) watched for a `Monitor`.
/// The monitor only judges with the thresholds it is given; this small owner holds the file
/// (`config::Reloadable<ThresholdSet>`), hands each good version to the monitor with
/// `Monitor::set_thresholds`, and each bad edit's errors with `Monitor::set_threshold_errors`
/// (the previous thresholds stay in use, and "vigil.monitor" reports the errors as WARN).
///
/// ```cpp
/// auto file = vigil::ThresholdFile::open("thresholds.yaml");
/// if (!file) { fputs(vigil::config::to_string(file.error()).c_str(), stderr); return 1; }
/// file->attach(monitor);   // now, and at the start of each monitor cycle when the file changed
/// ```
///
/// A deployment's `supervision: {thresholds: FILE}` is watched this way by `deploy::System`.
///
/// Thread safety: every member is thread-safe; `reload()`/`poll()` may run while the monitor's
/// thread polls. Not RT-safe (file I/O, allocation).

#include <cstdint>
#include <filesystem>
#include <memory>

#include "vigil/config/error.hpp"
#include "vigil/config/reloadable.hpp"
#include "vigil/expected.hpp"
#include "vigil/monitor/thresholds.hpp"

namespace vigil::monitor {

class Monitor;

/// A watched thresholds file. Move-only; destroying it detaches it from its monitor (the
/// monitor keeps the thresholds it was given last).
class ThresholdFile {
 public:
  /// Loads `path`. Fails with every error of the file.
  [[nodiscard]] static expected<ThresholdFile, config::ConfigErrors> open(
      const std::filesystem::path& path);

  ThresholdFile(ThresholdFile&&) noexcept;
  ThresholdFile& operator=(ThresholdFile&&) noexcept;
  ThresholdFile(const ThresholdFile&) = delete;
  ThresholdFile& operator=(const ThresholdFile&) = delete;
  /// Detaches from the monitor.
  ~ThresholdFile();

  /// Gives `monitor` the file's thresholds now and keeps it up to date: after each `reload()` or
  /// `poll()`, and, when `poll_each_cycle`, from a hook that polls the file at the start of each
  /// of the monitor's cycles (a change applies to the very cycle that saw it). One monitor at a
  /// time: attaching again detaches from the previous one. `monitor` must outlive the
  /// attachment (until `detach()` or this object's destruction).
  void attach(Monitor& monitor, bool poll_each_cycle = true);
  /// Stops updating the monitor (it keeps the thresholds it has). Idempotent.
  void detach();

  /// Re-reads the file now. On success returns the new generation and gives the monitor the
  /// new thresholds; on failure keeps the previous ones, gives the monitor the errors, and
  /// returns them.
  expected<std::uint64_t, config::ConfigErrors> reload();
  /// Reloads only when the file's modification time or size changed since the last attempt
  /// (see `config::Reloadable::poll`), with the same effect on the monitor as `reload()`.
  config::ReloadStatus poll();

  /// The thresholds of the last good version (never null).
  [[nodiscard]] std::shared_ptr<const ThresholdSet> current() const;
  /// 1 after `open()`, incremented by each successful reload.
  [[nodiscard]] std::uint64_t generation() const;
  /// The errors of the last attempt; empty when it succeeded.
  [[nodiscard]] config::ConfigErrors errors() const;
  /// The file.
  [[nodiscard]] const std::filesystem::path& path() const;

  struct State;  ///< defined in threshold_file.cpp

 private:
  explicit ThresholdFile(std::shared_ptr<State> state) noexcept;
  std::shared_ptr<State> state_;  // shared with the monitor's cycle hook
};

}  // namespace vigil::monitor

// The names a program writes, also in vigil (docs/design/modules.md).
namespace vigil {
using monitor::ThresholdFile;
}  // namespace vigil
