#pragma once
// Forked children for the multi-process tests: a pipe each way, "ready" from the child, "go"
// from the parent; a child left running is killed and reaped with its handle.
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "vigil/task/task.hpp"

namespace vigil::test {

using namespace std::chrono_literals;

// A forked child with a pipe each way: the child says "ready" (one byte), the parent says "go".
struct Child {
  pid_t pid = -1;
  int to_child = -1;
  int from_child = -1;
  bool reaped = false;

  // Waits for one byte from the child (false after `timeout`).
  bool wait_ready(std::chrono::milliseconds timeout = 10s) const {
    pollfd p{from_child, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout.count())) != 1) return false;
    char c = 0;
    return ::read(from_child, &c, 1) == 1;
  }
  void go() const {
    const char c = 'g';
    REQUIRE(::write(to_child, &c, 1) == 1);
  }
  int kill_and_reap(int sig) {
    ::kill(pid, sig);
    return reap();
  }
  int reap() {
    int status = 0;
    ::waitpid(pid, &status, 0);
    reaped = true;
    return status;
  }
  ~Child() {
    if (pid > 0 && !reaped) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
    if (to_child >= 0) ::close(to_child);
    if (from_child >= 0) ::close(from_child);
  }
};

// The child's side: tell the parent, wait for it.
struct ChildLink {
  int to_parent;
  int from_parent;
  void ready() const {
    const char c = 'r';
    (void)!::write(to_parent, &c, 1);
  }
  void wait_go() const {
    char c = 0;
    (void)!::read(from_parent, &c, 1);
  }
};

inline std::unique_ptr<Child> spawn(const std::function<void(const ChildLink&)>& body) {
  int down[2];
  int up[2];
  REQUIRE(::pipe(down) == 0);
  REQUIRE(::pipe(up) == 0);
  auto c = std::make_unique<Child>();
  c->pid = ::fork();
  REQUIRE(c->pid >= 0);
  if (c->pid == 0) {
    ::close(down[1]);
    ::close(up[0]);
    body(ChildLink{up[1], down[0]});
    ::_exit(0);
  }
  ::close(down[0]);
  ::close(up[1]);
  c->to_child = down[1];
  c->from_child = up[0];
  return c;
}

/// A component that does nothing: what the children run (the daemon sees its cycles).
class Ctl : public Task<Ctl> {
 public:
  Ctl(std::string name, Registry<task::Message>& registry) : Task(std::move(name), {}, registry) {}
  void on_update() {}
};

}  // namespace vigil::test
