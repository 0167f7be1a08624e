// Threads on both platforms: pthreads with explicit scheduling, affinity, names and prefaulted
// stacks. The pthread calls themselves come from the platform's backend (backend.hpp): glibc's on
// Linux; on Cobalt libcobalt's for SCHED_FIFO threads (Cobalt threads) and glibc's for the others
// (plain Linux threads). Everything else, checks, attributes and the start protocol, is this file.
#include "vigil/platform/thread.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <cstring>

#include "platform/posix/backend.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/platform/wait.hpp"

namespace vigil::platform {

struct Thread::State {
  pthread_t handle{};
  bool joinable = false;
  const detail::ThreadOps* ops = nullptr;
  std::atomic<int> tid{0};
  /// 0 until the new thread has named itself and published its TID (a wait_on word).
  std::atomic<std::uint32_t> started{0};
  std::function<void()> body;
  std::string name;
  std::size_t prefault = 0;
};

namespace {

thread_local int tls_tid = 0;

// On Cobalt a SCHED_FIFO thread runs this in primary mode (libcobalt hardened it before calling
// it): nothing here may issue a Linux system call, which would relax the thread before its first
// cycle. The name and the TID go through the backend (Cobalt system calls there), the start
// signal through wake_one (a Cobalt semaphore there).
void* thread_main(void* arg) {
  auto* state = static_cast<Thread::State*>(arg);
  // Linux: writes /proc/self/task/<tid>/comm. Cobalt thread: sets the Cobalt name and the Linux
  // comm in one Cobalt system call.
  state->ops->set_name(pthread_self(), state->name.c_str());
  state->tid.store(current_tid(), std::memory_order_relaxed);
  state->started.store(1, std::memory_order_release);
  wake_one(state->started);
  if (state->prefault > 0) prefault_stack(state->prefault);
  state->body();
  // Cobalt: libcobalt's trampoline clears PTHREAD_WARNSW after we return, so the exit path's
  // Linux system calls raise no SIGDEBUG.
  return nullptr;
}

std::string describe(const ThreadConfig& c, const char* label) {
  std::string s = fmt::format("thread '{}' ({}", c.name, to_string(c.policy));
  if (c.policy == SchedPolicy::Fifo) s += fmt::format(" priority {}", c.priority);
  if (c.cpu >= 0) s += fmt::format(", cpu {}", c.cpu);
  return s + label + ")";
}

}  // namespace

const detail::ThreadOps& detail::glibc_thread_ops() noexcept {
  // Plain names: vigil's executables are linked without libcobalt's --wrap list (cmake/
  // FindXenomai.cmake, Xenomai::cobalt_link), so these are glibc's on both platforms.
  static constexpr ThreadOps ops{"", &pthread_attr_init, &pthread_create, &pthread_join,
                                 &pthread_setname_np};
  return ops;
}

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
  const detail::ThreadOps& ops = detail::thread_ops(config);
  if (config.policy == SchedPolicy::Fifo) {
    // Cobalt: a SCHED_FIFO thread is a Cobalt thread, so libcobalt must have started (the first
    // such thread starts it when the program has not: on the main thread only). Linux: no-op.
    if (auto core = initialize(); !core) {
      return unexpected(Error{core.error().code, fmt::format("{}: {}", describe(config, ops.label),
                                                             core.error().message)});
    }
    // 1..99 on both platforms: Cobalt's SCHED_FIFO accepts up to 256, but libcobalt also sets
    // the Linux side of the thread, where the range is 1..99 (XENOMAI.md §3.3).
    const int lo = sched_get_priority_min(SCHED_FIFO);
    const int hi = sched_get_priority_max(SCHED_FIFO);
    if (config.priority < lo || config.priority > hi) {
      return unexpected(
          Error{EINVAL, fmt::format("{}: priority {} is outside {}..{}",
                                    describe(config, ops.label), config.priority, lo, hi)});
    }
  }
  if (config.cpu >= CPU_SETSIZE || config.cpu < -1 ||
      (config.cpu >= 0 && config.cpu >= cpu_count())) {
    return unexpected(
        Error{EINVAL, fmt::format("{}: cpu {} does not exist ({} CPUs online)",
                                  describe(config, ops.label), config.cpu, cpu_count())});
  }

  auto state = std::make_unique<State>();
  state->ops = &ops;
  state->body = std::move(body);
  state->name = config.name.substr(0, 15);
  // Never touch more than half of an explicit stack: the rest is the thread's own.
  state->prefault = config.stack_bytes > 0
                        ? std::min(config.prefault_stack_bytes, config.stack_bytes / 2)
                        : config.prefault_stack_bytes;

  pthread_attr_t attr;
  // Cobalt thread: libcobalt's attr_init, glibc's plus Cobalt's default stack size.
  ops.attr_init(&attr);
  struct AttrGuard {
    pthread_attr_t* a;
    ~AttrGuard() { pthread_attr_destroy(a); }
  } guard{&attr};

  int rc = 0;
  if (config.stack_bytes > 0) {
    const std::size_t size = config.stack_bytes < static_cast<std::size_t>(PTHREAD_STACK_MIN)
                                 ? static_cast<std::size_t>(PTHREAD_STACK_MIN)
                                 : config.stack_bytes;
    rc = pthread_attr_setstacksize(&attr, size);
    if (rc != 0) {
      return unexpected(Error{rc, fmt::format("{}: stack size {}: {}", describe(config, ops.label),
                                              size, std::strerror(rc))});
    }
  }
  // libcobalt too reads policy and priority from the attribute when it is PTHREAD_EXPLICIT_SCHED
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
    // One CPU, set before creation (glibc's call on both platforms): the Cobalt core pins each
    // thread to one CPU of the real-time set when it shadows it, and a later change costs a relax.
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(config.cpu), &set);
    rc = pthread_attr_setaffinity_np(&attr, sizeof(set), &set);
  }
  if (rc != 0) {
    return unexpected(
        Error{rc, fmt::format("{}: {}", describe(config, ops.label), std::strerror(rc))});
  }

  // Returns the error number itself: EPERM when Linux refuses SCHED_FIFO; on Cobalt also EAGAIN
  // when the core has no memory left, EINVAL for an attribute it rejects.
  rc = ops.create(&state->handle, &attr, &thread_main, state.get());
  if (rc != 0) {
    return unexpected(Error{
        rc, fmt::format("pthread_create {}: {}", describe(config, ops.label), std::strerror(rc))});
  }
  state->joinable = true;
  while (state->started.load(std::memory_order_acquire) == 0) wait_on(state->started, 0);

  Thread t;
  t.state_ = std::move(state);
  return t;
}

void Thread::join() noexcept {
  if (state_ && state_->joinable) {
    // Cobalt thread: libcobalt's join, glibc's and then a wait until the core dropped the thread.
    state_->ops->join(state_->handle, nullptr);
    state_->joinable = false;
  }
}

bool Thread::joinable() const noexcept { return state_ && state_->joinable; }

int Thread::tid() const noexcept {
  return state_ ? state_->tid.load(std::memory_order_acquire) : 0;
}

int current_tid() noexcept {
  if (tls_tid == 0) tls_tid = detail::query_current_tid();
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
  if (const int rc = detail::current_sched_param(&policy, &param); rc != 0) {
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
