#include "vigil/config/reloadable.hpp"

#include <system_error>

namespace vigil::config::detail {

ReloadableCore::ReloadableCore(std::filesystem::path path, ErasedLoader loader)
    : path_(std::move(path)), loader_(std::move(loader)) {}

ReloadableCore::Stamp ReloadableCore::stamp_now_() const {
  std::error_code ec;
  Stamp stamp;
  stamp.mtime = std::filesystem::last_write_time(path_, ec);
  if (ec) return Stamp{};
  stamp.size = std::filesystem::file_size(path_, ec);
  if (ec) stamp.size = 0;  // not a regular file: loading will say why
  stamp.exists = true;
  return stamp;
}

expected<std::uint64_t, ConfigErrors> ReloadableCore::reload() {
  const std::lock_guard lock(reload_mutex_);
  return reload_locked_(stamp_now_());
}

ReloadStatus ReloadableCore::poll() {
  const std::lock_guard lock(reload_mutex_);
  const Stamp now = stamp_now_();
  if (now == stamp_) return ReloadStatus::Unchanged;
  return reload_locked_(now).has_value() ? ReloadStatus::Reloaded : ReloadStatus::Failed;
}

expected<std::uint64_t, ConfigErrors> ReloadableCore::reload_locked_(const Stamp& stamp) {
  // The stamp is taken before reading: a write that lands during the read changes the file
  // again after the stamp, so the next poll() reloads once more instead of missing it.
  stamp_ = stamp;
  expected<Value, ConfigErrors> loaded = [&]() -> expected<Value, ConfigErrors> {
    expected<Node, ConfigErrors> root = load_file(path_);
    if (!root.has_value()) return vigil::unexpected<ConfigErrors>(std::move(root.error()));
    return loader_(*root);
  }();
  if (!loaded.has_value()) {
    const std::lock_guard lock(value_mutex_);
    last_errors_ = loaded.error();
    return vigil::unexpected<ConfigErrors>(std::move(loaded.error()));
  }
  std::uint64_t generation = 0;
  {
    const std::lock_guard lock(value_mutex_);
    value_ = *loaded;
    last_errors_.clear();
    generation = generation_.fetch_add(1) + 1;
  }
  notify_(*loaded, generation);
  return generation;
}

void ReloadableCore::notify_(const Value& value, std::uint64_t generation) noexcept {
  std::vector<std::pair<std::uint64_t, ErasedCallback>> subscribers;
  {
    const std::lock_guard lock(subscribers_mutex_);
    subscribers = subscribers_;
  }
  for (auto& [id, callback] : subscribers) callback(value, generation);
}

ReloadableCore::Value ReloadableCore::current() const {
  const std::lock_guard lock(value_mutex_);
  return value_;
}

std::uint64_t ReloadableCore::generation() const noexcept { return generation_.load(); }

ConfigErrors ReloadableCore::last_errors() const {
  const std::lock_guard lock(value_mutex_);
  return last_errors_;
}

std::uint64_t ReloadableCore::subscribe(ErasedCallback callback) {
  const std::lock_guard lock(subscribers_mutex_);
  const std::uint64_t id = next_id_++;
  subscribers_.emplace_back(id, std::move(callback));
  return id;
}

void ReloadableCore::unsubscribe(std::uint64_t id) {
  const std::lock_guard lock(subscribers_mutex_);
  std::erase_if(subscribers_, [id](const auto& s) { return s.first == id; });
}

}  // namespace vigil::config::detail
