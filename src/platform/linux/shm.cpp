// POSIX shared memory (shm_open, ftruncate, mmap), the /dev/shm listing and inotify watch, and
// the SIGBUS guard used to read mappings that another process may shrink.
#include "vigil/platform/shm.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <grp.h>
#include <sys/inotify.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csetjmp>
#include <csignal>
#include <cstring>
#include <mutex>
#include <utility>

namespace vigil::platform {

namespace {

constexpr const char* kShmDir = "/dev/shm";

Error os_error(int err, const std::string& what) {
  return Error(err, what + ": " + std::strerror(err));
}

ShmFileInfo info_of(const struct stat& st) {
  ShmFileInfo i;
  i.uid = st.st_uid;
  i.gid = st.st_gid;
  i.mode = st.st_mode & 07777;
  i.size = static_cast<std::uint64_t>(st.st_size);
  i.inode = st.st_ino;
  i.device = st.st_dev;
  return i;
}

bool valid_name(const std::string& name) {
  return name.size() >= 2 && name.size() < 250 && name[0] == '/' &&
         name.find('/', 1) == std::string::npos;
}

}  // namespace

SharedMemory::SharedMemory(SharedMemory&& o) noexcept
    : data_(std::exchange(o.data_, nullptr)),
      size_(std::exchange(o.size_, 0)),
      fd_(std::exchange(o.fd_, -1)),
      name_(std::move(o.name_)),
      info_(o.info_) {}

SharedMemory& SharedMemory::operator=(SharedMemory&& o) noexcept {
  if (this != &o) {
    reset();
    data_ = std::exchange(o.data_, nullptr);
    size_ = std::exchange(o.size_, 0);
    fd_ = std::exchange(o.fd_, -1);
    name_ = std::move(o.name_);
    info_ = o.info_;
  }
  return *this;
}

SharedMemory::~SharedMemory() { reset(); }

void SharedMemory::reset() noexcept {
  if (data_ != nullptr) ::munmap(data_, size_);
  if (fd_ >= 0) ::close(fd_);
  data_ = nullptr;
  size_ = 0;
  fd_ = -1;
}

expected<SharedMemory, Error> SharedMemory::create(const std::string& name, std::size_t size,
                                                   const ShmCreateOptions& options) {
  if (!valid_name(name)) {
    return unexpected<Error>(Error(EINVAL, "shared memory name '" + name + "' is not /NAME"));
  }
  if (size == 0)
    return unexpected<Error>(Error(EINVAL, "shared memory segment " + name + ": size 0"));
  std::optional<std::uint32_t> gid;
  std::uint32_t mode = options.mode & 0777;
  if (!options.group.empty()) {
    gid = group_id(options.group);
    if (!gid) {
      return unexpected<Error>(
          Error(EINVAL, "shared memory segment " + name + ": no group '" + options.group + "'"));
    }
    mode |= 0060;
  }
  // O_EXCL: never adopt a file someone else prepared. The umask cannot widen 0600, and fchmod
  // below sets the exact bits (the umask might have narrowed the group's).
  const int fd = ::shm_open(name.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return unexpected<Error>(os_error(errno, "shm_open(" + name + ", O_CREAT|O_EXCL)"));
  SharedMemory m;
  m.fd_ = fd;
  m.name_ = name;
  const auto fail = [&](const std::string& what) {
    const int err = errno;
    ::shm_unlink(name.c_str());
    return unexpected<Error>(os_error(err, what + " of shared memory segment " + name));
  };
  if (gid && ::fchown(fd, static_cast<uid_t>(-1), *gid) != 0) return fail("fchown");
  if (::fchmod(fd, mode) != 0) return fail("fchmod");
  if (::ftruncate(fd, static_cast<off_t>(size)) != 0) return fail("ftruncate");
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) return fail("mmap");
  m.data_ = p;
  m.size_ = size;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return fail("fstat");
  m.info_ = info_of(st);
  return m;
}

expected<SharedMemory, Error> SharedMemory::open(const std::string& name, std::size_t max_size) {
  if (!valid_name(name)) {
    return unexpected<Error>(Error(EINVAL, "shared memory name '" + name + "' is not /NAME"));
  }
  // O_NOFOLLOW: a symbolic link placed in /dev/shm is not followed elsewhere.
  const int fd = ::shm_open(name.c_str(), O_RDWR | O_CLOEXEC | O_NOFOLLOW, 0);
  if (fd < 0) return unexpected<Error>(os_error(errno, "shm_open(" + name + ")"));
  SharedMemory m;
  m.fd_ = fd;
  m.name_ = name;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return unexpected<Error>(os_error(errno, "fstat(" + name + ")"));
  if (!S_ISREG(st.st_mode)) {
    return unexpected<Error>(
        Error(EINVAL, "shared memory segment " + name + " is not a regular file"));
  }
  m.info_ = info_of(st);
  if (st.st_size <= 0) {
    return unexpected<Error>(
        Error(EINVAL, "shared memory segment " + name + " is empty (0 bytes)"));
  }
  if (static_cast<std::uint64_t>(st.st_size) > max_size) {
    return unexpected<Error>(Error(EFBIG, "shared memory segment " + name + " is " +
                                              std::to_string(st.st_size) + " bytes, more than " +
                                              std::to_string(max_size) + " accepted"));
  }
  const auto size = static_cast<std::size_t>(st.st_size);
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) return unexpected<Error>(os_error(errno, "mmap(" + name + ")"));
  m.data_ = p;
  m.size_ = size;
  return m;
}

expected<void, Error> SharedMemory::unlink() const {
  if (name_.empty()) return {};
  return unlink_shared_memory(name_);
}

expected<ShmFileInfo, Error> SharedMemory::stat() const {
  struct stat st {};
  if (fd_ < 0 || ::fstat(fd_, &st) != 0)
    return unexpected<Error>(os_error(errno, "fstat(" + name_ + ")"));
  return info_of(st);
}

expected<void, Error> unlink_shared_memory(const std::string& name) {
  if (::shm_unlink(name.c_str()) != 0 && errno != ENOENT) {
    return unexpected<Error>(os_error(errno, "shm_unlink(" + name + ")"));
  }
  return {};
}

std::vector<std::string> list_shared_memory(std::string_view prefix) {
  std::vector<std::string> out;
  DIR* d = ::opendir(kShmDir);
  if (d == nullptr) return out;
  while (const dirent* e = ::readdir(d)) {
    const std::string_view n(e->d_name);
    if (n.size() > prefix.size() && n.substr(0, prefix.size()) == prefix) {
      out.push_back("/" + std::string(n));
    }
  }
  ::closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

std::uint32_t effective_uid() noexcept { return ::geteuid(); }

std::optional<std::uint32_t> group_id(const std::string& name_or_number) {
  if (name_or_number.empty()) return std::nullopt;
  if (std::all_of(name_or_number.begin(), name_or_number.end(),
                  [](char c) { return c >= '0' && c <= '9'; }) &&
      name_or_number.size() < 10) {
    return static_cast<std::uint32_t>(std::stoul(name_or_number));
  }
  group g{};
  group* result = nullptr;
  std::vector<char> buf(16384);
  if (::getgrnam_r(name_or_number.c_str(), &g, buf.data(), buf.size(), &result) != 0 ||
      result == nullptr) {
    return std::nullopt;
  }
  return static_cast<std::uint32_t>(g.gr_gid);
}

// --- directory watch ------------------------------------------------------------------------

ShmDirectoryWatch::ShmDirectoryWatch(ShmDirectoryWatch&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)) {}
ShmDirectoryWatch& ShmDirectoryWatch::operator=(ShmDirectoryWatch&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
  }
  return *this;
}
ShmDirectoryWatch::~ShmDirectoryWatch() {
  if (fd_ >= 0) ::close(fd_);
}

expected<ShmDirectoryWatch, Error> ShmDirectoryWatch::open() {
  const int fd = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (fd < 0) return unexpected<Error>(os_error(errno, "inotify_init1"));
  if (::inotify_add_watch(fd, kShmDir, IN_CREATE | IN_DELETE | IN_MOVED_TO | IN_MOVED_FROM) < 0) {
    const int err = errno;
    ::close(fd);
    return unexpected<Error>(os_error(err, std::string("inotify_add_watch(") + kShmDir + ")"));
  }
  ShmDirectoryWatch w;
  w.fd_ = fd;
  return w;
}

bool ShmDirectoryWatch::consume(std::string_view prefix) noexcept {
  if (fd_ < 0) return false;
  bool any = false;
  alignas(inotify_event) char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n <= 0) break;
    for (ssize_t off = 0; off + static_cast<ssize_t>(sizeof(inotify_event)) <= n;) {
      inotify_event e{};
      std::memcpy(&e, buf + off, sizeof e);
      const std::size_t room = static_cast<std::size_t>(n - off) - sizeof e;
      const std::size_t len = std::min<std::size_t>(e.len, room);
      // The name is NUL-padded to `len` bytes.
      const char* name = buf + off + sizeof e;
      const std::string_view file(name, ::strnlen(name, len));
      if ((e.mask & IN_Q_OVERFLOW) != 0 || prefix.empty() ||
          file.substr(0, prefix.size()) == prefix) {
        any = true;
      }
      off += static_cast<ssize_t>(sizeof e + e.len);
    }
  }
  return any;
}

// --- SIGBUS guard ---------------------------------------------------------------------------

namespace {

thread_local sigjmp_buf* tls_guard = nullptr;
std::once_flag g_bus_once;
struct sigaction g_previous_bus {};

extern "C" void on_bus_error(int sig, siginfo_t* info, void* ctx) {
  if (sigjmp_buf* jb = tls_guard) {
    tls_guard = nullptr;
    siglongjmp(*jb, 1);
  }
  // Not inside run_guarded(): what would have happened without us. A previous handler (a crash
  // reporter, a sanitizer) is called; otherwise the default action is restored and returning
  // re-executes the faulting access, which then terminates the process.
  if ((g_previous_bus.sa_flags & SA_SIGINFO) != 0 && g_previous_bus.sa_sigaction != nullptr) {
    g_previous_bus.sa_sigaction(sig, info, ctx);
    return;
  }
  if (g_previous_bus.sa_handler != SIG_DFL && g_previous_bus.sa_handler != SIG_IGN) {
    g_previous_bus.sa_handler(sig);
    return;
  }
  struct sigaction sa {};
  sa.sa_handler = SIG_DFL;
  sigemptyset(&sa.sa_mask);
  sigaction(sig, &sa, nullptr);
}

void install_bus_handler() {
  struct sigaction sa {};
  sa.sa_sigaction = &on_bus_error;
  // SA_NODEFER: the jump leaves the handler without sigreturn, so SIGBUS must not stay blocked.
  sa.sa_flags = SA_SIGINFO | SA_NODEFER;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGBUS, &sa, &g_previous_bus);
}

}  // namespace

bool run_guarded(void (*fn)(void* ctx) noexcept, void* ctx) noexcept {
  std::call_once(g_bus_once, install_bus_handler);
  sigjmp_buf jb;
  // savemask = 0: no system call per guard (SA_NODEFER keeps SIGBUS unblocked after a jump).
  if (sigsetjmp(jb, 0) != 0) return false;
  tls_guard = &jb;
  fn(ctx);
  tls_guard = nullptr;
  return true;
}

}  // namespace vigil::platform
