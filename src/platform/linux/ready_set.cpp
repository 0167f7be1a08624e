// ReadySet: epoll, with nanosecond deadlines where the kernel has epoll_pwait2 (Linux >= 5.11).
#include "vigil/platform/ready_set.hpp"

#include <sys/epoll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <ctime>
#include <utility>

namespace vigil::platform {

ReadySet::ReadySet(ReadySet&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
ReadySet& ReadySet::operator=(ReadySet&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
  }
  return *this;
}
ReadySet::~ReadySet() {
  if (fd_ >= 0) ::close(fd_);
}

expected<ReadySet, Error> ReadySet::open() {
  ReadySet s;
  s.fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  if (s.fd_ < 0) return unexpected<Error>(Error(errno, "epoll_create1"));
  return s;
}

expected<void, Error> ReadySet::add(int fd, std::uint64_t tag) noexcept {
  epoll_event e{};
  e.events = EPOLLIN;  // hang-up and error are always reported
  e.data.u64 = tag;
  if (::epoll_ctl(fd_, EPOLL_CTL_ADD, fd, &e) != 0) {
    return unexpected<Error>(Error(errno, "epoll_ctl(ADD)"));
  }
  return {};
}

void ReadySet::remove(int fd) noexcept {
  if (fd_ >= 0 && fd >= 0) (void)::epoll_ctl(fd_, EPOLL_CTL_DEL, fd, nullptr);
}

int ReadySet::wait(Nanos deadline_ns, std::uint64_t* tags, std::size_t max) noexcept {
  constexpr std::size_t kBatch = 64;
  epoll_event events[kBatch];
  const int want = static_cast<int>(std::min(std::max<std::size_t>(max, 1), kBatch));
  for (;;) {
    const Nanos now = now_ns();
    const Nanos left = deadline_ns > now ? deadline_ns - now : 0;
    const timespec ts{static_cast<time_t>(left / kNanosPerSecond),
                      static_cast<long>(left % kNanosPerSecond)};
    int r = ::epoll_pwait2(fd_, events, want, &ts, nullptr);
    if (r < 0 && errno == ENOSYS) {
      // Before Linux 5.11: millisecond timeouts, rounded up (never wake before the deadline).
      const auto ms = static_cast<int>(
          std::min<Nanos>((left + kNanosPerMilli - 1) / kNanosPerMilli, 1'000'000));
      r = ::epoll_wait(fd_, events, want, ms);
    }
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return -errno;
    const int n = std::min(r, static_cast<int>(max));
    for (int i = 0; i < n; ++i) tags[i] = events[i].data.u64;
    return n;
  }
}

}  // namespace vigil::platform
