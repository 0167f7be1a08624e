#include "vigil/exec/periodic_activity.hpp"

#include <linux/capability.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <mutex>
#include <thread>

#include "support/drain.hpp"
#include "support/probe.hpp"
#include "support/proc_reader.hpp"

using namespace vigil;
using vigil::test::drain;
using vigil::test::only;
using vigil::test::Probe;

namespace {
void wait_cycles(const Probe& p, std::uint64_t n) {
  const auto deadline = platform::now_ns() + 10 * kNanosPerSecond;
  while (p.cycles() < n && platform::now_ns() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}
}  // namespace

TEST_CASE("Periodic tasks with equal parameters share one thread and run in order",
          "[exec][periodic]") {
  Registry<task::Message> reg;
  Probe a("a", {}, reg), b("b", {}, reg), c("c", {}, reg);
  std::mutex m;
  std::vector<char> order;
  a.work = [&] {
    std::lock_guard l(m);
    order.push_back('a');
  };
  b.work = [&] {
    std::lock_guard l(m);
    order.push_back('b');
  };
  c.work = [&] {
    std::lock_guard l(m);
    order.push_back('c');
  };
  const PeriodicConfig shared{.name = "shared", .period_ns = 2 * kNanosPerMilli};
  PeriodicConfig other = shared;
  other.name = "other";
  other.period_ns = 3 * kNanosPerMilli;
  PeriodicActivity aa(a, shared), ab(b, shared), ac(c, other);
  for (Probe* p : {&a, &b, &c}) REQUIRE(p->configure());
  REQUIRE(aa.start().has_value());
  REQUIRE(ab.start().has_value());
  REQUIRE(ac.start().has_value());
  wait_cycles(a, 20);
  wait_cycles(c, 20);
  aa.stop();
  ab.stop();
  ac.stop();
  CHECK(aa.info().tid == ab.info().tid);
  CHECK(aa.info().tid != ac.info().tid);
  CHECK(aa.info().tid != 0);
  CHECK(ab.info().tasks_on_thread.load() >= 1);
  // Within the shared thread, a always runs right before b.
  std::vector<char> ab_only;
  for (char ch : order) {
    if (ch != 'c') ab_only.push_back(ch);
  }
  REQUIRE(ab_only.size() >= 20);
  // b joined after a: skip a's first solo cycles, then the pattern is strictly a, b, a, b...
  std::size_t first_b = 0;
  while (first_b < ab_only.size() && ab_only[first_b] != 'b') ++first_b;
  bool alternating = true;
  for (std::size_t i = first_b + 1; i + 1 < ab_only.size(); i += 2) {
    alternating = alternating && ab_only[i] == 'a' && ab_only[i + 1] == 'b';
  }
  CHECK(alternating);
  // Each task's identity says where it ran.
  const auto info = only<task::TaskInfo>(drain(*a.port()));
  REQUIRE_FALSE(info.empty());
  CHECK(info.back().threaded);
  CHECK(info.back().tid == aa.info().tid);
  CHECK(info.back().period_ns == 2 * kNanosPerMilli);
  CHECK(a.state() == TaskState::Stopped);
  CHECK(a.stops == 1);
  CHECK(a.state_errors.empty());
}

TEST_CASE("share_thread = false gives a task its own thread", "[exec][periodic]") {
  Registry<task::Message> reg;
  Probe a("a", {}, reg), b("b", {}, reg);
  PeriodicConfig cfg{.name = "own", .period_ns = 2 * kNanosPerMilli, .share_thread = false};
  PeriodicActivity aa(a, cfg), ab(b, cfg);
  REQUIRE(a.configure());
  REQUIRE(b.configure());
  REQUIRE(aa.start().has_value());
  REQUIRE(ab.start().has_value());
  wait_cycles(a, 3);
  CHECK(aa.info().tid != ab.info().tid);
}

TEST_CASE("A FIFO activity's thread reads back its policy, priority and CPU from /proc",
          "[exec][periodic]") {
  if (!vigil::test::have_rt_privileges()) {
    WARN("skipped: no privilege for SCHED_FIFO");
    return;
  }
  Registry<task::Message> reg;
  Probe a("a", {}, reg);
  vigil::test::ProcThread proc;
  std::atomic<bool> read{false};
  a.work = [&] {
    if (!read.exchange(true)) proc = vigil::test::read_proc_thread(platform::current_tid());
  };
  const int cpu = platform::cpu_count() > 1 ? 1 : 0;
  PeriodicActivity act(a, {.name = "fifo",
                           .period_ns = kNanosPerMilli,
                           .policy = SchedPolicy::Fifo,
                           .priority = 70,
                           .cpu = cpu});
  REQUIRE(a.configure());
  REQUIRE(act.start().has_value());
  wait_cycles(a, 5);
  act.stop();
  CHECK(proc.policy == SCHED_FIFO);
  CHECK(proc.rt_priority == 70);
  CHECK(proc.cpus_allowed == std::to_string(cpu));
  CHECK(act.info().policy == SchedPolicy::Fifo);
  CHECK_FALSE(act.info().realtime_refused);
}

TEST_CASE("When SCHED_FIFO is refused the activity runs OTHER and says so", "[exec][periodic]") {
  // In a child process without CAP_SYS_NICE (and RLIMIT_RTPRIO 0), FIFO must be refused.
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    rlimit rl{0, 0};
    setrlimit(RLIMIT_RTPRIO, &rl);
    __user_cap_header_struct hdr{_LINUX_CAPABILITY_VERSION_3, 0};
    __user_cap_data_struct data[2] = {};
    syscall(SYS_capget, &hdr, data);
    data[0].effective &= ~(1U << CAP_SYS_NICE);
    data[0].permitted &= ~(1U << CAP_SYS_NICE);
    syscall(SYS_capset, &hdr, data);
    Registry<task::Message> reg;
    Probe a("a", {}, reg);
    PeriodicActivity act(a, {.name = "want-fifo",
                             .period_ns = kNanosPerMilli,
                             .policy = SchedPolicy::Fifo,
                             .priority = 50});
    if (!a.configure()) _exit(10);
    if (!act.start()) _exit(11);
    wait_cycles(a, 3);
    const bool ok = act.info().realtime_refused && act.info().policy == SchedPolicy::Other &&
                    act.info().requested_policy == SchedPolicy::Fifo && a.cycles() >= 3;
    act.stop();
    // And with fallback disabled, start() fails with the system's error.
    Probe b("b", {}, reg);
    PeriodicActivity strict(b, {.name = "strict",
                                .period_ns = kNanosPerMilli,
                                .policy = SchedPolicy::Fifo,
                                .priority = 50,
                                .fallback_to_other = false});
    if (!b.configure()) _exit(12);
    const auto r = strict.start();
    const bool refused = !r && r.error().code == EPERM;
    _exit(ok && refused ? 0 : 13);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
}

TEST_CASE("Overruns and skipped cycles are counted on a real thread", "[exec][periodic]") {
  Registry<task::Message> reg;
  Probe a("slow", {}, reg);
  a.work = [&] {
    if (a.updates == 5) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  };
  PeriodicActivity act(a, {.name = "slow", .period_ns = 2 * kNanosPerMilli});
  REQUIRE(a.configure());
  REQUIRE(act.start().has_value());
  wait_cycles(a, 10);
  act.stop();
  const auto samples = vigil::test::cycles_of(drain(*a.port()));
  REQUIRE(samples.size() >= 10);
  CHECK(samples[4].overrun);
  CHECK(samples.back().counters.overruns >= 1);
  CHECK(samples.back().counters.missed_cycles >= 4);  // 10 ms late at 2 ms: 4 or 5 releases skipped
  CHECK(samples[5].missed_before >= 4);
}

TEST_CASE("start() refuses a task that is not configured", "[exec][periodic]") {
  Registry<task::Message> reg;
  Probe a("a", {}, reg);
  PeriodicActivity act(a, {.name = "x", .period_ns = kNanosPerMilli});
  const auto r = act.start();
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message.find("configure it before starting") != std::string::npos);
  a.script.refuse_start = true;
  REQUIRE(a.configure());
  const auto r2 = act.start();
  REQUIRE_FALSE(r2.has_value());
  CHECK(r2.error().message.find("refused to start") != std::string::npos);
  CHECK_FALSE(act.running());
}
