#include "vigil/monitor/check.hpp"

#include <exception>
#include <typeinfo>

namespace vigil::monitor {

std::size_t CheckList::remove(std::string_view name) {
  return std::erase_if(checks_, [&](const auto& c) { return c->name() == name; });
}

void CheckList::run(const CheckInput& in, Report& out) const {
  for (const auto& c : checks_) {
    // A broken check must not hide the other checks' findings, nor stop the monitor.
    try {
      c->run(in, out);
    } catch (const std::exception& e) {
      out.merge(StatusLevel::Error, "check " + std::string(c->name()) + " failed: " + e.what());
    } catch (...) {
      out.merge(StatusLevel::Error, "check " + std::string(c->name()) + " failed");
    }
  }
}

std::vector<std::string> CheckList::names() const {
  std::vector<std::string> out;
  out.reserve(checks_.size());
  for (const auto& c : checks_) out.emplace_back(c->name());
  return out;
}

}  // namespace vigil::monitor
