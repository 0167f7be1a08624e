// The line loop and error policy every CAN text log reader shares.
#include "can/log/line_reader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <utility>

namespace vigil::can {

std::string ParseError::to_string() const {
  if (column == 0) return fmt::format("{}:{}: {}", source, line, message);
  return fmt::format("{}:{}:{}: {}", source, line, column, message);
}

}  // namespace vigil::can

namespace vigil::can::detail {

namespace {
// Large enough that a read system call moves many lines at once, small enough to stay in L2.
constexpr std::size_t kBlockBytes = std::size_t{64} * 1024;
}  // namespace

LineReader::LineReader(std::streambuf* source, std::size_t max_line_bytes)
    : source_(source),
      max_line_(std::max<std::size_t>(max_line_bytes, 1)),
      // Room for a whole maximal line (plus "\r\n") and a block behind it, so that a line of
      // the maximal length never looks too long only because the buffer is full.
      capacity_(std::max(kBlockBytes, 2 * (max_line_ + 2))),
      buffer_(std::make_unique<char[]>(capacity_)) {}

bool LineReader::fill() {
  if (eof_ || source_ == nullptr) {
    eof_ = true;
    return false;
  }
  if (begin_ > 0) {
    // Keep the partial line at the front so that the next block is appended to it.
    std::memmove(buffer_.get(), buffer_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  const auto got =
      source_->sgetn(buffer_.get() + end_, static_cast<std::streamsize>(capacity_ - end_));
  if (got <= 0) {
    eof_ = true;
    return false;
  }
  end_ += static_cast<std::size_t>(got);
  return true;
}

void LineReader::strip_bom(std::string_view& line) const noexcept {
  // Some Windows tools start text files with a UTF-8 byte order mark; it is not part of line 1.
  if (line_number_ == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);
}

LineReader::Status LineReader::skip_long_line() {
  // Drop buffered bytes until the end of the current line; memory stays one buffer.
  for (;;) {
    const char* start = buffer_.get() + begin_;
    if (const void* nl = std::memchr(start, '\n', end_ - begin_)) {
      begin_ = static_cast<std::size_t>(static_cast<const char*>(nl) - buffer_.get()) + 1;
      return Status::TooLong;
    }
    begin_ = end_ = 0;
    if (!fill()) return Status::TooLong;
  }
}

LineReader::Status LineReader::next(std::string_view& line) {
  for (;;) {
    const char* start = buffer_.get() + begin_;
    const std::size_t pending = end_ - begin_;
    if (const void* nl = std::memchr(start, '\n', pending)) {
      const auto* stop = static_cast<const char*>(nl);
      std::size_t len = static_cast<std::size_t>(stop - start);
      begin_ += len + 1;
      ++line_number_;
      if (len > 0 && start[len - 1] == '\r') --len;
      if (len > max_line_) return Status::TooLong;
      line = std::string_view(start, len);
      strip_bom(line);
      return Status::Line;
    }
    if (pending > max_line_ + 1) {  // no newline in more than a line's worth (+ its '\r')
      ++line_number_;
      return skip_long_line();
    }
    if (!fill()) {
      if (end_ == begin_) return Status::End;
      // Last line without a newline (fill() may have moved it to the front).
      const char* last = buffer_.get() + begin_;
      std::size_t len = end_ - begin_;
      begin_ = end_;
      ++line_number_;
      if (last[len - 1] == '\r') --len;
      if (len > max_line_) return Status::TooLong;
      line = std::string_view(last, len);
      strip_bom(line);
      return Status::Line;
    }
  }
}

TextLog::TextLog(std::unique_ptr<std::istream> owned, std::istream& in, std::string source,
                 ReaderOptions options)
    : owned_(std::move(owned)),
      lines_(in.rdbuf(), options.max_line_bytes),
      source_(std::move(source)),
      options_(std::move(options)) {}

Problem TextLog::too_long() const {
  return Problem{0, fmt::format("line longer than {} bytes", lines_.max_line_bytes())};
}

ParseError TextLog::record(Problem& problem) {
  ++malformed_;
  ParseError e{source_, lines_.line_number(), static_cast<std::uint32_t>(problem.offset + 1),
               std::move(problem.message)};
  if (options_.on_error) options_.on_error(e);
  if (kept_.size() < options_.max_kept_errors) kept_.push_back(e);
  return e;
}

bool TextLog::report(Problem& problem) {
  ParseError e = record(problem);
  if (options_.on_malformed == OnMalformed::Skip) return true;
  failure_ = Error{EINVAL, e.to_string()};
  return false;
}

void TextLog::fail(Problem& problem) {
  ParseError e = record(problem);
  failure_ = Error{EINVAL, e.to_string()};
}

expected<std::unique_ptr<std::istream>, Error> open_input(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return unexpected(
        Error{EISDIR, fmt::format("{}: cannot read: {}", path, std::strerror(EISDIR))});
  }
  errno = 0;
  auto in = std::make_unique<std::ifstream>(path, std::ios::in | std::ios::binary);
  if (!in->is_open()) {
    const int err = errno != 0 ? errno : ENOENT;
    return unexpected(Error{err, fmt::format("{}: cannot open: {}", path, std::strerror(err))});
  }
  return std::unique_ptr<std::istream>(std::move(in));
}

}  // namespace vigil::can::detail
