#include "vigil/export/textfile.hpp"

#include <fmt/format.h>

#include <fstream>
#include <system_error>

#include "vigil/export/prometheus.hpp"

namespace vigil::exporter {

expected<void, Error> write_textfile(const std::filesystem::path& path,
                                     const MetricsSnapshot& snapshot) {
  const std::string text = render_metrics(snapshot, ExpositionFormat::Prometheus);
  std::filesystem::path tmp = path;
  tmp += ".tmp";  // not *.prom: the collector ignores it
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) {
      return vigil::unexpected(
          Error(fmt::format("textfile {}: cannot create {} (does the directory exist and is it "
                            "writable?)",
                            path.string(), tmp.string())));
    }
    f.write(text.data(), static_cast<std::streamsize>(text.size()));
    f.flush();
    if (!f) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      return vigil::unexpected(Error(
          fmt::format("textfile {}: cannot write {} (disk full?)", path.string(), tmp.string())));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    return vigil::unexpected(
        Error(ec.value(), fmt::format("textfile {}: cannot rename {} to it: {}", path.string(),
                                      tmp.string(), ec.message())));
  }
  return {};
}

}  // namespace vigil::exporter
