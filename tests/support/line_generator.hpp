#pragma once
// A streambuf that makes up its lines on the fly, for the log readers' tests (candump, TRC): a
// test can stream gigabytes through a reader without storing them anywhere.
#include <array>
#include <cstddef>
#include <cstdint>
#include <streambuf>

namespace vigil::test {

/// `lines` lines, line i made by `make(i, buffer) -> length` into a buffer of 256 bytes.
template <class Make>
class LineGenerator : public std::streambuf {
 public:
  LineGenerator(std::uint64_t lines, Make make) : lines_(lines), make_(make) {}

 protected:
  int_type underflow() override {
    if (next_ == lines_) return traits_type::eof();
    const std::size_t n = make_(next_++, buffer_.data());
    setg(buffer_.data(), buffer_.data(), buffer_.data() + n);
    return traits_type::to_int_type(buffer_[0]);
  }

 private:
  std::uint64_t lines_;
  std::uint64_t next_ = 0;
  Make make_;
  std::array<char, 256> buffer_{};
};

}  // namespace vigil::test
