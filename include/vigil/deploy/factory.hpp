#pragma once
/// @file
/// The component factory: deployment files name component types; user code registers its types
/// with one line.
///
/// ```cpp
/// class Motor : public vigil::Task<Motor> {
///  public:
///   explicit Motor(const vigil::deploy::ComponentContext& c)
///       : Task(c.name, c.supervision, c.registry()),
///         gain_(c.parameters.optional("gain", 1.0, vigil::config::positive())) {}
///   void on_update();
///  private:
///   double gain_;
/// };
/// VIGIL_REGISTER_COMPONENT(Motor, "robot.motor");   // the one registration line
/// ```
///
/// Parameters are read from the component's `parameters:` mapping in the deployment file; a bad
/// value is reported with file:line:col like every other configuration error.

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vigil/bus/registry.hpp"
#include "vigil/config/node.hpp"
#include "vigil/service/reactions.hpp"
#include "vigil/task/messages.hpp"
#include "vigil/task/supervision.hpp"
#include "vigil/task/task_core.hpp"

namespace vigil::deploy {

class System;

/// What a component is built from.
struct ComponentContext {
  std::string name;
  SupervisionOptions supervision;
  /// The component's `parameters:` mapping (undefined when absent). Read with the config API.
  config::Node parameters;
  Registry<task::Message>* registry_ptr = nullptr;
  /// The running system (for services such as CAN sniffers); null outside a System.
  System* system = nullptr;

  [[nodiscard]] Registry<task::Message>& registry() const noexcept { return *registry_ptr; }
};

/// Makes a component; throws or returns null to fail (reported with the component's location).
using ComponentMaker = std::function<std::unique_ptr<TaskCore>(const ComponentContext&)>;

/// Component types by name. Thread-safe. Not RT-safe.
class ComponentFactory {
 public:
  struct Type {
    std::string name;
    std::string description;
    ComponentMaker make;
  };

  /// The process's factory, where VIGIL_REGISTER_COMPONENT registers.
  static ComponentFactory& instance();

  /// Registers `type`; returns false (and keeps the first) if the name is taken.
  bool add(std::string type, ComponentMaker make, std::string description = {});

  /// Registers T, constructible from `const ComponentContext&`.
  template <class T>
  bool add(std::string type, std::string description = {}) {
    static_assert(std::is_base_of_v<TaskCore, T>,
                  "a registered component must derive from vigil::TaskCore (e.g. vigil::Task<T>)");
    static_assert(std::is_constructible_v<T, const ComponentContext&>,
                  "a registered component needs a constructor T(const vigil::deploy::"
                  "ComponentContext&)");
    return add(
        std::move(type),
        [](const ComponentContext& c) -> std::unique_ptr<TaskCore> {
          return std::make_unique<T>(c);
        },
        std::move(description));
  }

  /// The type named `name`, or null.
  [[nodiscard]] const Type* find(std::string_view name) const;
  /// Every registered type, sorted by name.
  [[nodiscard]] std::vector<Type> types() const;

  /// A reaction handler a deployment's `reactions:` may name (`handlers: [name]`), called on the
  /// reaction thread with its budget (0: the default, 10 ms; vigil/service/reactions.hpp).
  struct Handler {
    std::string name;
    std::string description;
    service::ReactionHandler fn;
    Nanos budget_ns = 0;
  };
  /// Registers handler `name`; returns false (and keeps the first) if the name is taken.
  bool add_handler(std::string name, service::ReactionHandler fn, Nanos budget_ns = 0,
                   std::string description = {});
  /// Every registered handler, sorted by name.
  [[nodiscard]] std::vector<Handler> handlers() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, Type, std::less<>> types_;
  std::map<std::string, Handler, std::less<>> handlers_;
};

}  // namespace vigil::deploy

#define VIGIL_DEPLOY_CONCAT_(a, b) a##b
#define VIGIL_DEPLOY_CONCAT(a, b) VIGIL_DEPLOY_CONCAT_(a, b)
/// Registers component type `Type` under `name` in the process's factory, at static
/// initialisation. Use it once, in a .cpp file that is linked into the program.
#define VIGIL_REGISTER_COMPONENT(Type, name)                                            \
  [[maybe_unused]] static const bool VIGIL_DEPLOY_CONCAT(vigil_registered_, __LINE__) = \
      ::vigil::deploy::ComponentFactory::instance().add<Type>(name)
