#include "vigil/task/task_core.hpp"

#include <cstdio>
#include <exception>
#include <typeinfo>

namespace vigil::task {

TaskCore::TaskCore(std::string name) : name_(std::move(name)) {}
TaskCore::~TaskCore() = default;

void TaskCore::on_transition(TaskState, TaskState, Hook, bool, std::string_view) noexcept {}

void TaskCore::on_exception(Hook hook, std::string_view type, std::string_view what) noexcept {
  std::fprintf(stderr, "vigil: %s: %s hook threw %.*s: %.*s\n", name_.c_str(), to_string(hook),
               static_cast<int>(type.size()), type.data(), static_cast<int>(what.size()),
               what.data());
}

void TaskCore::transition(TaskState to, Hook hook, std::string_view reason) noexcept {
  const TaskState from = state();
  // Report first, then publish: whoever sees the new state also sees the report pushed.
  on_transition(from, to, hook, false, reason);
  state_.store(to, std::memory_order_release);
}

void TaskCore::refuse(Hook hook, std::string_view reason) noexcept {
  const TaskState s = state();
  on_transition(s, s, hook, true, refusal_.empty() ? reason : std::string_view(refusal_));
  refusal_.clear();
}

template <class F>
bool TaskCore::run_hook(Hook hook, F&& f) noexcept {
  try {
    return f();
  } catch (const std::exception& e) {
    on_exception(hook, typeid(e).name(), e.what());
  } catch (...) {
    on_exception(hook, "unknown", "");
  }
  if (state() != TaskState::FatalError) transition(TaskState::Exception, hook, "exception");
  return false;
}

bool TaskCore::configure() {
  const TaskState s = state();
  if (s != TaskState::PreOperational && s != TaskState::Stopped) return false;
  bool threw = true;
  const bool ok = run_hook(Hook::Configure, [&] {
    const bool r = configure_hook();
    threw = false;
    return r;
  });
  if (threw) return false;
  if (ok) {
    transition(TaskState::Stopped, Hook::Configure);
  } else if (state() != TaskState::PreOperational) {
    refuse(Hook::Configure, "configure hook returned false");
    transition(TaskState::PreOperational, Hook::Configure, "configure refused");
  } else {
    refuse(Hook::Configure, "configure hook returned false");
  }
  return ok;
}

bool TaskCore::start() {
  if (state() != TaskState::Stopped) return false;
  bool threw = true;
  const bool ok = run_hook(Hook::Start, [&] {
    const bool r = start_hook();
    threw = false;
    return r;
  });
  if (threw) return false;
  if (ok) {
    transition(TaskState::Running, Hook::Start);
  } else {
    refuse(Hook::Start, "start hook returned false");
  }
  return ok;
}

bool TaskCore::update() noexcept {
  own_context_ = CycleContext{};
  return update(own_context_);
}

bool TaskCore::update(CycleContext& context) noexcept {
  if (state() != TaskState::Running) return false;
  context_ = &context;
  run_hook(Hook::Update, [&] {
    update_hook();
    return true;
  });
  context_ = &own_context_;
  return state() == TaskState::Running;
}

bool TaskCore::stop() {
  if (state() != TaskState::Running) return false;
  bool threw = true;
  const bool ok = run_hook(Hook::Stop, [&] {
    const bool r = stop_hook();
    threw = false;
    return r;
  });
  if (threw) return false;
  if (ok) {
    transition(TaskState::Stopped, Hook::Stop);
  } else {
    refuse(Hook::Stop, "stop hook returned false");
  }
  return ok;
}

bool TaskCore::cleanup() {
  if (state() != TaskState::Stopped) return false;
  bool threw = true;
  const bool ok = run_hook(Hook::Cleanup, [&] {
    const bool r = cleanup_hook();
    threw = false;
    return r;
  });
  if (threw) return false;
  if (ok) {
    transition(TaskState::PreOperational, Hook::Cleanup);
  } else {
    refuse(Hook::Cleanup, "cleanup hook returned false");
  }
  return ok;
}

bool TaskCore::recover() {
  if (state() != TaskState::Exception) return false;
  transition(TaskState::PreOperational, Hook::None, "recovered");
  return true;
}

void TaskCore::raise_exception(Hook hook, std::string_view type, std::string_view reason) noexcept {
  if (state() != TaskState::Running) return;
  on_exception(hook, type, reason);
  transition(TaskState::Exception, hook, reason);
}

void TaskCore::fatal(std::string_view reason) noexcept {
  if (state() == TaskState::FatalError) return;
  transition(TaskState::FatalError, Hook::None, reason);
}

}  // namespace vigil::task
