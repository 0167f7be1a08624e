#pragma once
// Probe components for tests: they check their own state inside every hook (Orocos'
// taskstates_test) and can be told to refuse, throw, allocate, sleep or burn time.
#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "vigil/task/task.hpp"

namespace vigil::test {

struct ProbeScript {
  bool refuse_configure = false, refuse_start = false, refuse_stop = false, refuse_cleanup = false;
  bool throw_configure = false, throw_start = false, throw_stop = false, throw_cleanup = false;
  std::uint64_t throw_update_at = 0;    // cycle number (1-based) that throws
  std::uint64_t allocate_every = 0;     // allocate on every Nth cycle
  std::uint64_t sleep_every = 0;        // sleep 1 ms on every Nth cycle
  std::uint64_t touch_pages_every = 0;  // touch fresh pages on every Nth cycle
};

template <class Traits = DefaultTaskTraits>
class BasicProbe : public Task<BasicProbe<Traits>, Traits> {
  using Base = Task<BasicProbe<Traits>, Traits>;

 public:
  explicit BasicProbe(std::string name, SupervisionOptions options = {},
                      Registry<task::Message>& registry = default_registry())
      : Base(std::move(name), options, registry) {}

  ProbeScript script;
  std::uint64_t updates = 0;
  int configures = 0, starts = 0, stops = 0, cleanups = 0;
  std::vector<std::string> state_errors;  // a hook ran in the wrong state
  std::function<void()> work;             // extra work in on_update

  bool on_configure() {
    ++configures;
    expect(this->state() == TaskState::PreOperational || this->state() == TaskState::Stopped,
           "configure");
    if (script.throw_configure) throw std::runtime_error("configure failed");
    return !script.refuse_configure;
  }
  bool on_start() {
    ++starts;
    expect(this->state() == TaskState::Stopped, "start");
    if (script.throw_start) throw std::logic_error("start failed");
    return !script.refuse_start;
  }
  void on_update() {
    ++updates;
    expect(this->state() == TaskState::Running, "update");
    if (script.throw_update_at != 0 && updates == script.throw_update_at) {
      throw std::out_of_range("update failed at cycle " + std::to_string(updates));
    }
    if (script.allocate_every != 0 && updates % script.allocate_every == 0) {
      auto* p = new int(static_cast<int>(updates));
      asm volatile("" : : "g"(p) : "memory");
      delete p;
    }
    if (script.sleep_every != 0 && updates % script.sleep_every == 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (script.touch_pages_every != 0 && updates % script.touch_pages_every == 0) {
      touch_fresh_pages();
    }
    if (work) work();
  }
  bool on_stop() {
    ++stops;
    expect(this->state() == TaskState::Running, "stop");
    if (script.throw_stop) throw std::runtime_error("stop failed");
    return !script.refuse_stop;
  }
  bool on_cleanup() {
    ++cleanups;
    expect(this->state() == TaskState::Stopped, "cleanup");
    if (script.throw_cleanup) throw std::runtime_error("cleanup failed");
    return !script.refuse_cleanup;
  }

 private:
  void expect(bool ok, const char* hook) {
    if (!ok) state_errors.push_back(std::string(hook) + " in " + to_string(this->state()));
  }
  static void touch_fresh_pages();
};

using Probe = BasicProbe<>;

}  // namespace vigil::test

#include <sys/mman.h>

template <class Traits>
void vigil::test::BasicProbe<Traits>::touch_fresh_pages() {
  // mmap is not a heap allocation; the 4 pages it maps fault on first touch.
  constexpr std::size_t kBytes = std::size_t{4} * 4096;
  void* m = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (m == MAP_FAILED) return;
  auto* b = static_cast<volatile unsigned char*>(m);
  for (std::size_t i = 0; i < kBytes; i += 4096) b[i] = 1;
  munmap(m, kBytes);
}
