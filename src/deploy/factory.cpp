#include "vigil/deploy/factory.hpp"

namespace vigil::deploy {

ComponentFactory& ComponentFactory::instance() {
  static ComponentFactory factory;
  return factory;
}

bool ComponentFactory::add(std::string type, ComponentMaker make, std::string description) {
  std::lock_guard lock(mutex_);
  std::string key = type;
  return types_
      .emplace(std::move(key), Type{std::move(type), std::move(description), std::move(make)})
      .second;
}

const ComponentFactory::Type* ComponentFactory::find(std::string_view name) const {
  std::lock_guard lock(mutex_);
  const auto it = types_.find(name);
  return it == types_.end() ? nullptr : &it->second;
}

std::vector<ComponentFactory::Type> ComponentFactory::types() const {
  std::lock_guard lock(mutex_);
  std::vector<Type> out;
  out.reserve(types_.size());
  for (const auto& [name, t] : types_) out.push_back(t);
  return out;
}

bool ComponentFactory::add_handler(std::string name, service::ReactionHandler fn, Nanos budget_ns,
                                   std::string description) {
  std::lock_guard lock(mutex_);
  std::string key = name;
  return handlers_
      .emplace(std::move(key),
               Handler{std::move(name), std::move(description), std::move(fn), budget_ns})
      .second;
}

std::vector<ComponentFactory::Handler> ComponentFactory::handlers() const {
  std::lock_guard lock(mutex_);
  std::vector<Handler> out;
  out.reserve(handlers_.size());
  for (const auto& [name, h] : handlers_) out.push_back(h);
  return out;
}

}  // namespace vigil::deploy
