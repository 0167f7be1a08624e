// Cobalt threads: libcobalt's pthread_create, which starts a glibc thread, "shadows" it into the
// Cobalt core and hardens it to primary mode before the start routine runs (XENOMAI.md §3.3).
//
// Why real-time threads must be created here: a thread made by std::thread or by any code not
// linked with libcobalt's wrappers is a plain Linux thread; Cobalt services then fail with EPERM
// or, when they have a Linux fallback, silently run with Linux timing. vigil calls __RT(name)
// (= __cobalt_<name>) explicitly, so this file creates Cobalt threads even in an executable that
// was linked without the --wrap list.
#include "vigil/platform/thread.hpp"

#include "platform/cobalt/build_check.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <cstring>

#include "vigil/platform/memory.hpp"
#include "vigil/platform/wait.hpp"

// Xenomai headers last: they define macros (list_*, container_of, ...) C++ headers must not see.
#include <cobalt/sys/cobalt.h>
#include <cobalt/wrappers.h>

namespace vigil::platform {

struct Thread::State {
  pthread_t handle{};
  bool joinable = false;
  std::atomic<int> tid{0};
  /// 0 until the new thread has named itself and published its TID (a wait_on word).
  std::atomic<std::uint32_t> started{0};
  std::function<void()> body;
  std::string name;
  std::size_t prefault = 0;
};

namespace {

// Cobalt's SCHED_FIFO accepts 1..256, but libcobalt also sets the Linux side of the thread, where
// the range is 1..99; vigil keeps the portable range on both platforms (XENOMAI.md §3.3).
constexpr int kFifoMin = 1;
constexpr int kFifoMax = 99;

thread_local int tls_tid = 0;

// Runs in primary mode (libcobalt hardened the thread before calling it). Nothing here may issue
// a Linux system call, which would relax the thread before its first cycle: the name and the TID
// go through Cobalt system calls, the start signal through a Cobalt semaphore (wait.cpp).
void* thread_main(void* arg) {
  auto* state = static_cast<Thread::State*>(arg);
  // Sets the Cobalt name and the Linux comm in one Cobalt system call ("current" mode).
  __RT(pthread_setname_np)(pthread_self(), state->name.c_str());
  state->tid.store(current_tid(), std::memory_order_relaxed);
  state->started.store(1, std::memory_order_release);
  wake_one(state->started);
  if (state->prefault > 0) prefault_stack(state->prefault);
  state->body();
  // libcobalt's trampoline clears PTHREAD_WARNSW after we return, so the exit path's Linux
  // system calls raise no SIGDEBUG.
  return nullptr;
}

std::string describe(const ThreadConfig& c) {
  std::string s = fmt::format("thread '{}' ({}", c.name, to_string(c.policy));
  if (c.policy == SchedPolicy::Fifo) s += fmt::format(" priority {}", c.priority);
  if (c.cpu >= 0) s += fmt::format(", cpu {}", c.cpu);
  return s + ", Cobalt)";
}

}  // namespace

Thread::Thread() noexcept = default;
Thread::Thread(Thread&&) noexcept = default;
Thread& Thread::operator=(Thread&& other) noexcept {
  if (this != &other) {
    join();
    state_ = std::move(other.state_);
  }
  return *this;
}
Thread::~Thread() { join(); }

expected<Thread, Error> Thread::spawn(const ThreadConfig& config, std::function<void()> body) {
  if (config.policy == SchedPolicy::Fifo &&
      (config.priority < kFifoMin || config.priority > kFifoMax)) {
    return unexpected(
        Error{EINVAL, fmt::format("{}: priority {} is outside {}..{}", describe(config),
                                  config.priority, kFifoMin, kFifoMax)});
  }
  if (config.cpu >= CPU_SETSIZE || config.cpu < -1 ||
      (config.cpu >= 0 && config.cpu >= cpu_count())) {
    return unexpected(Error{EINVAL, fmt::format("{}: cpu {} does not exist ({} CPUs online)",
                                                describe(config), config.cpu, cpu_count())});
  }

  auto state = std::make_unique<State>();
  state->body = std::move(body);
  state->name = config.name.substr(0, 15);
  // Never touch more than half of an explicit stack: the rest is the thread's own.
  state->prefault = config.stack_bytes > 0
                        ? std::min(config.prefault_stack_bytes, config.stack_bytes / 2)
                        : config.prefault_stack_bytes;

  pthread_attr_t attr;
  // libcobalt's attr_init: glibc's, plus Cobalt's default stack size.
  __RT(pthread_attr_init)(&attr);
  struct AttrGuard {
    pthread_attr_t* a;
    ~AttrGuard() { pthread_attr_destroy(a); }
  } guard{&attr};

  int rc = 0;
  if (config.stack_bytes > 0) {
    const std::size_t size = config.stack_bytes < static_cast<std::size_t>(PTHREAD_STACK_MIN)
                                 ? static_cast<std::size_t>(PTHREAD_STACK_MIN)
                                 : config.stack_bytes;
    if ((rc = pthread_attr_setstacksize(&attr, size)) != 0) {
      return unexpected(Error{
          rc, fmt::format("{}: stack size {}: {}", describe(config), size, std::strerror(rc))});
    }
  }
  // libcobalt reads policy and priority from the attribute when it is PTHREAD_EXPLICIT_SCHED
  // and applies them to both the Linux and the Cobalt side of the new thread.
  rc = pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
  if (rc == 0) {
    rc = pthread_attr_setschedpolicy(&attr,
                                     config.policy == SchedPolicy::Fifo ? SCHED_FIFO : SCHED_OTHER);
  }
  if (rc == 0) {
    sched_param param{};
    param.sched_priority = config.policy == SchedPolicy::Fifo ? config.priority : 0;
    rc = pthread_attr_setschedparam(&attr, &param);
  }
  if (rc == 0 && config.cpu >= 0) {
    // One CPU, set before creation (glibc call, not wrapped): the Cobalt core pins each thread
    // to one CPU of the real-time set when it shadows it, and a later change costs a relax.
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(config.cpu), &set);
    rc = pthread_attr_setaffinity_np(&attr, sizeof(set), &set);
  }
  if (rc != 0) {
    return unexpected(Error{rc, fmt::format("{}: {}", describe(config), std::strerror(rc))});
  }

  // Returns the error number itself: EPERM when the Linux side refuses SCHED_FIFO, EAGAIN when
  // the Cobalt core has no memory left, EINVAL for an attribute it rejects.
  rc = __RT(pthread_create)(&state->handle, &attr, &thread_main, state.get());
  if (rc != 0) {
    return unexpected(
        Error{rc, fmt::format("pthread_create {}: {}", describe(config), std::strerror(rc))});
  }
  state->joinable = true;
  while (state->started.load(std::memory_order_acquire) == 0) wait_on(state->started, 0);

  Thread t;
  t.state_ = std::move(state);
  return t;
}

void Thread::join() noexcept {
  if (state_ && state_->joinable) {
    // libcobalt's join: glibc's, then waits until the Cobalt core has dropped the thread too.
    __RT(pthread_join)(state_->handle, nullptr);
    state_->joinable = false;
  }
}

bool Thread::joinable() const noexcept { return state_ && state_->joinable; }

int Thread::tid() const noexcept {
  return state_ ? state_->tid.load(std::memory_order_acquire) : 0;
}

int current_tid() noexcept {
  if (tls_tid == 0) {
    // A Cobalt system call in "current" mode: a primary-mode caller stays in primary mode
    // (gettid() would relax it). A thread unknown to Cobalt gets -ESRCH and asks Linux.
    const pid_t pid = cobalt_thread_pid(pthread_self());
    tls_tid = pid > 0 ? static_cast<int>(pid) : static_cast<int>(::syscall(SYS_gettid));
  }
  return tls_tid;
}

int cpu_count() noexcept {
  const long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n > 0 ? static_cast<int>(n) : 1;
}

expected<SchedInfo, Error> current_sched_info() {
  SchedInfo info;
  int policy = 0;
  sched_param param{};
  // Cobalt's view for a Cobalt thread (libcobalt falls back to glibc's for other threads). A
  // SCHED_OTHER Cobalt thread reports Cobalt's SCHED_WEAK class, which maps to Other here.
  if (const int rc = __RT(pthread_getschedparam)(pthread_self(), &policy, &param); rc != 0) {
    return unexpected(Error{rc, fmt::format("pthread_getschedparam: {}", std::strerror(rc))});
  }
  info.policy = policy == SCHED_FIFO ? SchedPolicy::Fifo : SchedPolicy::Other;
  info.priority = info.policy == SchedPolicy::Fifo ? param.sched_priority : 0;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (pthread_getaffinity_np(pthread_self(), sizeof(set), &set) == 0 && CPU_COUNT(&set) == 1) {
    for (int i = 0; i < CPU_SETSIZE; ++i) {
      if (CPU_ISSET(static_cast<unsigned>(i), &set)) {
        info.pinned_cpu = i;
        break;
      }
    }
  }
  return info;
}

}  // namespace vigil::platform
