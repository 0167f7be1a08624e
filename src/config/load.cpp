#include "vigil/config/load.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <memory>
#include <set>
#include <system_error>
#include <unordered_map>

namespace vigil::config {
namespace {

std::string join(std::string_view path, std::string_view key) {
  return path.empty() ? std::string(key) : fmt::format("{}.{}", path, key);
}

void sort_by_location(ConfigErrors& errors) {
  std::stable_sort(errors.begin(), errors.end(), [](const ConfigError& a, const ConfigError& b) {
    return std::pair(a.line, a.column) < std::pair(b.line, b.column);
  });
}

// yaml-cpp keeps every pair of a mapping but lookups find only the first: a repeated key would
// be silently ignored. Walks the whole document and reports each repetition where it is written.
class DuplicateFinder {
 public:
  DuplicateFinder(const std::string& file, std::string_view text, ConfigErrors& out)
      : file_(file), text_(text), out_(out) {}

  void walk(const YAML::Node& n, const std::string& path) {
    if (!n.IsMap() && !n.IsSequence()) return;
    // An alias is the anchored node itself, and `&a [*a]` is a cycle: visit each container once,
    // identified by where it starts and what it is.
    if (!visited_.emplace(n.Mark().pos, static_cast<int>(n.Type())).second) return;
    if (n.IsSequence()) {
      std::size_t index = 0;
      for (const auto& item : n) walk(item, fmt::format("{}[{}]", path, index++));
      return;
    }
    std::unordered_map<std::string, YAML::Mark> first;
    // Range-for binds each pair by value: yaml-cpp's operator-> returns a temporary proxy.
    for (const auto& pair : n) {
      const YAML::Node& key = pair.first;
      if (!key.IsScalar()) {
        walk(pair.second, path);
        continue;
      }
      const std::string child = join(path, key.Scalar());
      const auto [previous, inserted] = first.emplace(key.Scalar(), key.Mark());
      if (!inserted) {
        const auto [line, column] = detail::locate(text_, key.Mark());
        const auto [first_line, first_column] = detail::locate(text_, previous->second);
        out_.push_back({file_, line, column, child,
                        fmt::format("duplicate key (first defined at line {}, column {})",
                                    first_line, first_column)});
      }
      walk(pair.second, child);
    }
  }

 private:
  const std::string& file_;
  std::string_view text_;
  ConfigErrors& out_;
  std::set<std::pair<int, int>> visited_;
};

struct FileCloser {
  void operator()(std::FILE* f) const noexcept { std::fclose(f); }
};

vigil::unexpected<ConfigErrors> file_error(const std::string& name, int err) {
  return vigil::unexpected<ConfigErrors>(
      ConfigErrors{{name, 0, 0, "",
                    fmt::format("cannot read file: {}",
                                std::error_code(err, std::generic_category()).message())}});
}

}  // namespace

expected<Node, ConfigErrors> load_string(std::string_view text, std::string name) {
  std::string owned(text);
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(owned);
  } catch (const YAML::Exception& e) {
    const auto [line, column] = detail::locate(owned, e.mark);
    return vigil::unexpected<ConfigErrors>(
        ConfigErrors{{std::move(name), line, column, "", e.msg}});
  }
  ConfigErrors errors;
  if (documents.size() > 1) {
    const auto [line, column] = detail::locate(owned, documents[1].Mark());
    errors.push_back({name, line, column, "",
                      "a file must hold a single YAML document; a second one starts here"});
  }
  const YAML::Node root = documents.empty() ? YAML::Node(YAML::NodeType::Null) : documents[0];
  DuplicateFinder(name, owned, errors).walk(root, "");
  if (!errors.empty()) {
    sort_by_location(errors);
    return vigil::unexpected<ConfigErrors>(std::move(errors));
  }
  return detail::NodeAccess::make_root(std::move(name), std::move(owned), root);
}

expected<Node, ConfigErrors> load_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  errno = 0;
  const std::unique_ptr<std::FILE, FileCloser> file(std::fopen(name.c_str(), "rb"));
  if (!file) return file_error(name, errno != 0 ? errno : EIO);
  std::string text;
  char buffer[16 * 1024];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, file.get())) > 0) text.append(buffer, n);
  if (std::ferror(file.get())) return file_error(name, errno != 0 ? errno : EIO);
  return load_string(text, name);
}

namespace detail {

ConfigError loader_exception_error(const Node& root, std::exception_ptr e) {
  try {
    std::rethrow_exception(std::move(e));
  } catch (const YAML::Exception& ex) {
    // A loader that read yaml() directly and misused it: yaml-cpp knows where.
    const auto [line, column] = NodeAccess::text_location(root, ex.mark);
    return {root.file(), line, column, "", fmt::format("the loader failed: {}", ex.msg)};
  } catch (const std::exception& ex) {
    return {root.file(), 0, 0, "", fmt::format("the loader failed: {}", ex.what())};
  } catch (...) {
    return {root.file(), 0, 0, "", "the loader failed with an unknown exception"};
  }
}

ConfigErrors merge_errors(const Node& root, ConfigErrors loader_errors, bool failed) {
  ConfigErrors all = root.errors();
  for (ConfigError& e : loader_errors) {
    if (std::find(all.begin(), all.end(), e) == all.end()) all.push_back(std::move(e));
  }
  if (failed && all.empty()) {
    all.push_back({root.file(), 0, 0, "", "the loader rejected the document without saying why"});
  }
  sort_by_location(all);
  return all;
}

}  // namespace detail

}  // namespace vigil::config
