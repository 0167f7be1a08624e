// Start of libcobalt, after the program has parsed its own command line.
//
// vigil's executables and shared libraries are linked with `xeno-config --cobalt --ldflags
// --no-auto-init` (Xenomai::cobalt_link, cmake/FindXenomai.cmake): no bootstrap.o, no --wrap=main.
// With the automatic start-up, libcobalt read /proc/self/cmdline in a constructor and acted on
// its own long options before main(): `vigil --version` printed "based on Xenomai/cobalt v3.2.7"
// and ended the process, `--help` printed Xenomai's option list, `--verbose`, `--quiet`, `--trace`
// and any unambiguous prefix of those (`--verb`) vanished from argv (lib/boilerplate/setup.c,
// parse_base_options(); lib/cobalt/init.c adds --main-prio and --print-buffer-*, v3.2.7).
//
// Here, xenomai_init() gets the program name only (initialize()), or what the program hands it
// (initialize(argc, argv)), once, on the main thread: __xenomai_init() records the caller as the
// process's main thread and cobalt_init() shadows the caller into the core.
#include "vigil/platform/process.hpp"

#include "platform/cobalt/build_check.hpp"
#include "platform/cobalt/core.hpp"

#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <mutex>

// Xenomai headers last: they define macros (panic, trace_me, ...) C++ headers must not see.
#include <xenomai/init.h>

namespace vigil::platform {

namespace detail {
std::atomic<bool> g_cobalt_ready{false};
}  // namespace detail

namespace {

std::mutex g_init_mutex;  // glibc's, like every mutex of vigil (docs/design/platform.md)

bool on_main_thread() noexcept { return ::syscall(SYS_gettid) == ::getpid(); }

// Holds g_init_mutex; Cobalt is not initialised yet.
expected<void, Error> start_cobalt(int* argc, char* const** argv) {
  if (!on_main_thread()) {
    return unexpected(Error{
        EPERM,
        "Xenomai Cobalt is not initialised yet and this is not the main thread: call "
        "vigil::platform::initialize() from main() first (libcobalt makes the calling thread the "
        "process's first Cobalt thread, which must be the main thread)"});
  }
  // Ends the process with libcobalt's own message when the kernel has no Cobalt core
  // ("Cobalt core not enabled in kernel") or cannot lock memory ("mlockall: ...").
  xenomai_init(argc, argv);
  detail::g_cobalt_ready.store(true, std::memory_order_release);
  return {};
}

}  // namespace

expected<void, Error> initialize() noexcept {
  if (detail::cobalt_ready()) return {};
  try {
    const std::lock_guard lock(g_init_mutex);
    if (detail::cobalt_ready()) return {};
    // The program name alone: libcobalt looks for none of its options and keeps its defaults.
    char* args[] = {program_invocation_name, nullptr};
    int argc = 1;
    char* const* argv = args;
    return start_cobalt(&argc, &argv);
  } catch (...) {  // std::mutex::lock's system_error, bad_alloc of the message
    return unexpected(Error{EAGAIN, "Xenomai Cobalt initialisation: out of resources"});
  }
}

expected<void, Error> initialize(int& argc, char**& argv) noexcept {
  try {
    const std::lock_guard lock(g_init_mutex);
    if (detail::cobalt_ready()) {
      return unexpected(
          Error{EALREADY,
                "Xenomai Cobalt is already initialised: the options in argv were not read (call "
                "vigil::platform::initialize(argc, argv) before any other vigil call that needs "
                "Cobalt)"});
    }
    int n = argc;
    char* const* v = argv;
    auto r = start_cobalt(&n, &v);
    if (r) {
      // libcobalt's own copy of the arguments (strdup'ed, never freed), without its options.
      argc = n;
      argv = const_cast<char**>(v);  // NOLINT(cppcoreguidelines-pro-type-const-cast)
    }
    return r;
  } catch (...) {
    return unexpected(Error{EAGAIN, "Xenomai Cobalt initialisation: out of resources"});
  }
}

bool initialized() noexcept { return detail::cobalt_ready(); }

}  // namespace vigil::platform
