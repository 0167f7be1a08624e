#include "vigil/deploy/extension.hpp"

#include <map>
#include <mutex>

namespace vigil::deploy {

namespace {
struct ExtensionRegistry {
  std::mutex mutex;
  std::map<std::string, ExtensionMaker, std::less<>> makers;
};
ExtensionRegistry& registry() {
  static ExtensionRegistry r;  // function-local: safe to use from static initialisers
  return r;
}
}  // namespace

void register_extension(std::string section, ExtensionMaker maker) {
  auto& r = registry();
  std::lock_guard lock(r.mutex);
  r.makers[std::move(section)] = std::move(maker);
}

ExtensionMaker find_extension(std::string_view section) {
  auto& r = registry();
  std::lock_guard lock(r.mutex);
  const auto it = r.makers.find(section);
  return it == r.makers.end() ? ExtensionMaker{} : it->second;
}

std::vector<std::string> registered_extensions() {
  auto& r = registry();
  std::lock_guard lock(r.mutex);
  std::vector<std::string> names;
  names.reserve(r.makers.size());
  for (const auto& [name, maker] : r.makers) names.push_back(name);
  return names;
}

}  // namespace vigil::deploy
