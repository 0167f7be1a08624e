#include "vigil/log/sinks.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

namespace vigil::log {

namespace {

const char* color_of(Level l) noexcept {
  switch (l) {
    case Level::Debug:
      return "\x1b[2m";  // dim
    case Level::Info:
      return "";
    case Level::Warn:
      return "\x1b[33m";  // yellow
    case Level::Error:
    case Level::Off:
      return "\x1b[31m";  // red
  }
  return "";
}

}  // namespace

std::string format_line(const Line& line, const LineFormat& format) {
  std::string out;
  out.reserve(64 + line.component.size() + line.text.size());
  const double seconds = static_cast<double>(line.time_ns) * 1e-9;
  const char* color = format.color ? color_of(line.level) : "";
  const bool colored = *color != '\0';
  fmt::format_to(std::back_inserter(out), "[{:13.6f}] {}{:<5}{} ", seconds, color,
                 to_string(line.level), colored ? "\x1b[0m" : "");
  if (format.component) {
    out += line.component;
    out += ' ';
  }
  fmt::format_to(std::back_inserter(out), "#{}: {}", line.cycle, line.text);
  if (format.source && !line.file.empty()) {
    // The file's name without its directories: enough to find it, short enough to read.
    const std::size_t slash = line.file.find_last_of('/');
    const std::string_view name =
        slash == std::string_view::npos ? line.file : line.file.substr(slash + 1);
    fmt::format_to(std::back_inserter(out), " ({}:{})", name, line.line);
  }
  return out;
}

// --- StreamSink ------------------------------------------------------------------------------

void StreamSink::write(const Line& line) noexcept {
  try {
    std::string s = format_line(line, format_);
    s += '\n';
    std::fwrite(s.data(), 1, s.size(), stream_);
  } catch (...) {  // allocation failure: the line is lost, the supervisor keeps running
  }
}

void StreamSink::flush() noexcept { std::fflush(stream_); }

// --- RotatingFileSink ------------------------------------------------------------------------

expected<std::unique_ptr<RotatingFileSink>, Error> RotatingFileSink::open(
    RotatingFileOptions options) {
  if (options.path.empty()) return unexpected(Error("log file: the path is empty"));
  if (options.max_bytes == 0) {
    return unexpected(Error(fmt::format("log file {}: max_bytes must be > 0", options.path)));
  }
  if (options.max_files == 0) {
    return unexpected(Error(fmt::format("log file {}: max_files must be >= 1", options.path)));
  }
  std::unique_ptr<RotatingFileSink> sink(new RotatingFileSink(std::move(options)));
  const std::string& path = sink->options_.path;
  sink->file_ = std::fopen(path.c_str(), "a");
  if (sink->file_ == nullptr) {
    const int e = errno;
    return unexpected(
        Error(e, fmt::format("log file {}: cannot open: {}", path, std::strerror(e))));
  }
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  sink->size_ = ec ? 0 : size;
  return sink;
}

RotatingFileSink::~RotatingFileSink() {
  if (file_ != nullptr) std::fclose(file_);
}

void RotatingFileSink::fail(std::string message) noexcept {
  ++errors_;
  try {
    last_error_ = std::move(message);
  } catch (...) {
  }
}

void RotatingFileSink::rotate() noexcept {
  try {
    if (file_ != nullptr) {
      std::fclose(file_);
      file_ = nullptr;
    }
    const std::string& base = options_.path;
    const auto name = [&](unsigned i) { return i == 0 ? base : base + "." + std::to_string(i); };
    std::error_code ec;
    if (options_.max_files > 1) {
      std::filesystem::remove(name(options_.max_files - 1), ec);  // the oldest goes
      for (unsigned i = options_.max_files - 1; i-- > 0;) {
        if (!std::filesystem::exists(name(i), ec)) continue;
        std::filesystem::rename(name(i), name(i + 1), ec);
        if (ec)
          fail(fmt::format("log file {}: cannot rename to {}: {}", name(i), name(i + 1),
                           ec.message()));
      }
    }
    // max_files == 1: the file is started again ("w" truncates it).
    file_ = std::fopen(base.c_str(), "w");
    size_ = 0;
    ++rotations_;
    if (file_ == nullptr) {
      fail(
          fmt::format("log file {}: cannot reopen after rotation: {}", base, std::strerror(errno)));
    }
  } catch (...) {
    fail("log file: rotation failed (out of memory)");
  }
}

void RotatingFileSink::write(const Line& line) noexcept {
  try {
    std::string s = format_line(line, options_.format);
    s += '\n';
    if (size_ > 0 && size_ + s.size() > options_.max_bytes) rotate();
    if (file_ == nullptr) {
      // A failed rotation left no file: try again at the next line.
      file_ = std::fopen(options_.path.c_str(), "a");
      if (file_ == nullptr) {
        fail(fmt::format("log file {}: cannot open: {}", options_.path, std::strerror(errno)));
        return;
      }
    }
    if (std::fwrite(s.data(), 1, s.size(), file_) != s.size()) {
      fail(fmt::format("log file {}: write failed: {}", options_.path, std::strerror(errno)));
    }
    size_ += s.size();
  } catch (...) {
    fail("log file: line lost (out of memory)");
  }
}

void RotatingFileSink::flush() noexcept {
  if (file_ == nullptr || std::fflush(file_) == 0) return;
  try {
    fail(fmt::format("log file {}: flush failed: {}", options_.path, std::strerror(errno)));
  } catch (...) {
    ++errors_;
  }
}

// --- TailSink --------------------------------------------------------------------------------

void TailSink::write(const Line& line) noexcept {
  try {
    std::string s = format_line(line, format_);
    std::lock_guard lock(mutex_);
    ++total_;
    if (capacity_ == 0) return;
    if (lines_.size() == capacity_) lines_.pop_front();
    lines_.push_back(std::move(s));
  } catch (...) {
  }
}

std::vector<std::string> TailSink::lines() const {
  std::lock_guard lock(mutex_);
  return {lines_.begin(), lines_.end()};
}

std::uint64_t TailSink::total() const {
  std::lock_guard lock(mutex_);
  return total_;
}

}  // namespace vigil::log
