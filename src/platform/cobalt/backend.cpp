// Cobalt backend of the shared POSIX part (src/platform/posix/backend.hpp): which threads are
// Cobalt threads, and the libcobalt calls that make them.
//
// The decision, once per thread, here: a SCHED_FIFO thread (a component's activity) is made by
// libcobalt's pthread_create, which starts a glibc thread, "shadows" it into the Cobalt core and
// hardens it to primary mode before the start routine runs (XENOMAI.md §3.3). It uses Cobalt
// services only: clock and sleeps (clock.cpp), waits (wait.cpp, Cobalt semaphores), and takes no
// lock on its real-time path. Every other thread (supervisor, monitor, exporters, servers, the
// SCHED_OTHER fallback of an activity) is a plain Linux thread made by glibc's pthread_create:
// Cobalt never shadows it, and like every other object of the program it uses glibc's mutexes,
// condition variables and rwlocks throughout. That is consistent because vigil's executables are
// linked without libcobalt's --wrap list (`xeno-config --cobalt --ldflags`, Xenomai::cobalt_link):
// std::mutex, std::condition_variable and std::shared_mutex are glibc's in every object, whatever
// thread takes them (docs/design/platform.md, "One kind of thread, one kind of lock").
//
// Every Cobalt call is named explicitly with __RT(name) (= __cobalt_<name>), or is a Cobalt-only
// function (cobalt_thread_pid), so this file does not depend on symbol wrapping.
#include "platform/posix/backend.hpp"

#include "platform/cobalt/build_check.hpp"
#include "platform/cobalt/core.hpp"

#include <pthread.h>
#include <sys/syscall.h>
#include <unistd.h>

// Xenomai headers last: they define macros (list_*, container_of, ...) C++ headers must not see.
#include <cobalt/sys/cobalt.h>
#include <cobalt/wrappers.h>

namespace vigil::platform::detail {

namespace {

int cobalt_attr_init(pthread_attr_t* attr) { return __RT(pthread_attr_init)(attr); }
int cobalt_create(pthread_t* thread, const pthread_attr_t* attr, void* (*start)(void*), void* arg) {
  return __RT(pthread_create)(thread, attr, start, arg);
}
int cobalt_join(pthread_t thread, void** result) { return __RT(pthread_join)(thread, result); }
// Sets the Cobalt name and the Linux comm in one Cobalt system call ("current" mode: a
// primary-mode caller stays in primary mode).
int cobalt_set_name(pthread_t thread, const char* name) {
  return __RT(pthread_setname_np)(thread, name);
}

constexpr ThreadOps kCobaltOps{", Cobalt", &cobalt_attr_init, &cobalt_create, &cobalt_join,
                               &cobalt_set_name};

}  // namespace

const ThreadOps& thread_ops(const ThreadConfig& config) noexcept {
  return config.policy == SchedPolicy::Fifo ? kCobaltOps : glibc_thread_ops();
}

int query_current_tid() noexcept {
  // A Cobalt system call in "current" mode: a primary-mode caller stays in primary mode
  // (gettid() would relax it). A thread unknown to Cobalt gets -ESRCH and asks Linux.
  const pid_t pid = cobalt_thread_pid(pthread_self());
  return pid > 0 ? static_cast<int>(pid) : static_cast<int>(::syscall(SYS_gettid));
}

int current_sched_param(int* policy, sched_param* param) noexcept {
  // Cobalt's view for a Cobalt thread (libcobalt falls back to glibc's for other threads). A
  // SCHED_OTHER Cobalt thread (main, shadowed by libcobalt's start-up, initialize()) reports
  // Cobalt's SCHED_WEAK class, which current_sched_info() maps to Other.
  return __RT(pthread_getschedparam)(pthread_self(), policy, param);
}

// libcobalt's initialisation (initialize(), core.cpp; setup_realtime_process() calls it first)
// calls mlockall(MCL_CURRENT | MCL_FUTURE) and ends the program if that fails; a thread shadowed
// while memory is unlocked gets SIGDEBUG_NOMLOCK (XENOMAI.md §3.4). So memory is locked once
// Cobalt runs and must stay locked: `lock_memory = false` cannot unlock it.
bool memory_always_locked() noexcept { return cobalt_ready(); }

}  // namespace vigil::platform::detail
