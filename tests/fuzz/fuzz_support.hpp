#pragma once
// Shared by the YAML fuzz targets: what every configuration load must guarantee, whatever the
// input: it ends (libFuzzer's -timeout), its memory is bounded (-rss_limit_mb), and a failure
// comes with at least one error, each naming the file, listed at most kMaxErrorsListed + 1 times.
#include <cstddef>
#include <cstdint>
#include <string>

#include "vigil/config/load.hpp"

namespace vigil::fuzz {

inline void check(bool ok) {
  if (!ok) __builtin_trap();
}

inline void check_errors(const config::ConfigErrors& errors, const std::string& name) {
  check(!errors.empty());
  check(errors.size() <= config::kMaxErrorsListed + 1);
  for (const config::ConfigError& e : errors) {
    check(e.file == name);
    check(!e.message.empty());
    check(e.line >= 0 && e.column >= 0);
    (void)e.to_string();
  }
}

template <class R>
void check_result(const R& r, const std::string& name) {
  if (!r.has_value()) check_errors(r.error(), name);
}

}  // namespace vigil::fuzz
