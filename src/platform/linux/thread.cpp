// Linux threads: pthreads with explicit scheduling, affinity, names and prefaulted stacks.
#include "vigil/platform/thread.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstring>

#include "vigil/platform/memory.hpp"

namespace vigil::platform {

struct Thread::State {
  pthread_t handle{};
  bool joinable = false;
  std::atomic<int> tid{0};
  std::function<void()> body;
  std::string name;
  std::size_t prefault = 0;
};

namespace {

thread_local int tls_tid = 0;

void* thread_main(void* arg) {
  auto* state = static_cast<Thread::State*>(arg);
  state->tid.store(current_tid(), std::memory_order_release);
  state->tid.notify_all();
  if (state->prefault > 0) prefault_stack(state->prefault);
  state->body();
  return nullptr;
}

std::string describe(const ThreadConfig& c) {
  std::string s = fmt::format("thread '{}' ({}", c.name, to_string(c.policy));
  if (c.policy == SchedPolicy::Fifo) s += fmt::format(" priority {}", c.priority);
  if (c.cpu >= 0) s += fmt::format(", cpu {}", c.cpu);
  return s + ")";
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
  if (config.policy == SchedPolicy::Fifo) {
    const int lo = sched_get_priority_min(SCHED_FIFO);
    const int hi = sched_get_priority_max(SCHED_FIFO);
    if (config.priority < lo || config.priority > hi) {
      return unexpected(Error{EINVAL, fmt::format("{}: priority {} is outside {}..{}",
                                                  describe(config), config.priority, lo, hi)});
    }
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
  pthread_attr_init(&attr);
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
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(config.cpu), &set);
    rc = pthread_attr_setaffinity_np(&attr, sizeof(set), &set);
  }
  if (rc != 0) {
    return unexpected(Error{rc, fmt::format("{}: {}", describe(config), std::strerror(rc))});
  }

  rc = pthread_create(&state->handle, &attr, &thread_main, state.get());
  if (rc != 0) {
    return unexpected(
        Error{rc, fmt::format("pthread_create {}: {}", describe(config), std::strerror(rc))});
  }
  state->joinable = true;
  pthread_setname_np(state->handle, state->name.c_str());
  state->tid.wait(0, std::memory_order_acquire);

  Thread t;
  t.state_ = std::move(state);
  return t;
}

void Thread::join() noexcept {
  if (state_ && state_->joinable) {
    pthread_join(state_->handle, nullptr);
    state_->joinable = false;
  }
}

bool Thread::joinable() const noexcept { return state_ && state_->joinable; }

int Thread::tid() const noexcept {
  return state_ ? state_->tid.load(std::memory_order_acquire) : 0;
}

int current_tid() noexcept {
  if (tls_tid == 0) tls_tid = static_cast<int>(::syscall(SYS_gettid));
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
  if (const int rc = pthread_getschedparam(pthread_self(), &policy, &param); rc != 0) {
    return unexpected(Error{rc, fmt::format("pthread_getschedparam: {}", std::strerror(rc))});
  }
  info.policy = policy == SCHED_FIFO ? SchedPolicy::Fifo : SchedPolicy::Other;
  info.priority = param.sched_priority;
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
