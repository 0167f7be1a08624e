#include "vigil/monitor/status.hpp"

#include <utility>

namespace vigil::monitor {

std::optional<StatusLevel> parse_status_level(std::string_view text) noexcept {
  for (StatusLevel l :
       {StatusLevel::Ok, StatusLevel::Warn, StatusLevel::Error, StatusLevel::Stale}) {
    if (text == to_string(l)) return l;
  }
  return std::nullopt;
}

Status::Status(StatusLevel level, std::string message) { merge(level, std::move(message)); }

void Status::merge(StatusLevel level, std::string message) {
  level_ = worst(level_, level);
  if (!message.empty()) messages_.push_back(StatusMessage{level, std::move(message)});
}

void Status::merge(const Status& other) {
  level_ = worst(level_, other.level_);
  messages_.insert(messages_.end(), other.messages_.begin(), other.messages_.end());
}

std::string Status::summary(std::string_view separator) const {
  std::string out;
  for (const auto& m : messages_) {
    if (!out.empty()) out += separator;
    out += m.text;
  }
  return out;
}

void Status::clear() noexcept {
  level_ = StatusLevel::Ok;
  messages_.clear();
}

}  // namespace vigil::monitor
