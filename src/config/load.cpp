#include "vigil/config/load.hpp"

#include <fmt/format.h>
#include <yaml-cpp/depthguard.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <memory>
#include <set>
#include <system_error>
#include <unordered_map>

#include "config/document.hpp"
#include "config/screen.hpp"

namespace vigil::config {
namespace {

std::string join(std::string_view path, std::string_view key) {
  return path.empty() ? std::string(key) : fmt::format("{}.{}", path, key);
}

// yaml-cpp keeps every pair of a mapping but lookups find only the first: a repeated key would
// be silently ignored. Walks the whole document and reports each repetition where it is written.
class DuplicateFinder {
 public:
  DuplicateFinder(const detail::Document& doc, ConfigErrors& out)
      : file_(doc.file), doc_(doc), out_(out) {}

  void walk(const YAML::Node& n, const std::string& path) {
    if (!n.IsMap() && !n.IsSequence()) return;
    // An alias is the anchored node itself: visit each container once, identified by where it
    // starts and what it is (recursive aliases are refused before this runs).
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
        const auto [line, column] = doc_.locate(key.Mark());
        const auto [first_line, first_column] = doc_.locate(previous->second);
        out_.push_back({file_, line, column, child,
                        fmt::format("duplicate key (first defined at line {}, column {})",
                                    first_line, first_column)});
      }
      walk(pair.second, child);
    }
  }

 private:
  const std::string& file_;
  const detail::Document& doc_;
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

vigil::unexpected<ConfigErrors> refuse(const detail::Document& doc, const YAML::Mark& mark,
                                       std::string message) {
  const auto [line, column] = doc.locate(mark);
  return vigil::unexpected<ConfigErrors>(ConfigErrors{{doc.file, line, column, "", message}});
}

std::string too_large() {
  return fmt::format("file is larger than {} MiB: not a configuration file", kMaxFileBytes >> 20);
}

}  // namespace

expected<Node, ConfigErrors> load_string(std::string_view text, std::string name) {
  if (text.size() > kMaxFileBytes) {
    return vigil::unexpected<ConfigErrors>(ConfigErrors{{name, 0, 0, "", too_large()}});
  }
  const std::shared_ptr<detail::Document> doc =
      detail::NodeAccess::make_document(std::move(name), std::string(text));
  YAML::Node root;
  try {
    // Pass 1 (builds nothing): limits, recursive aliases, a second document; it always ends,
    // where YAML::LoadAll may loop forever. Pass 2: yaml-cpp builds the first document only.
    if (std::optional<detail::Refusal> refused = detail::screen_yaml(doc->text)) {
      return refuse(*doc, refused->mark, std::move(refused->message));
    }
    root = YAML::Load(doc->text);
  } catch (const YAML::DeepRecursion& e) {
    return refuse(*doc, e.mark,
                  fmt::format("nesting deeper than {} levels (mappings and sequences inside each "
                              "other)",
                              e.depth()));
  } catch (const YAML::Exception& e) {
    return refuse(*doc, e.mark, e.msg);
  }
  ConfigErrors errors;
  DuplicateFinder(*doc, errors).walk(root, "");
  if (!errors.empty()) {
    detail::tidy_errors(errors);
    return vigil::unexpected<ConfigErrors>(std::move(errors));
  }
  return detail::NodeAccess::make_root(doc, root);
}

expected<Node, ConfigErrors> load_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  errno = 0;
  const std::unique_ptr<std::FILE, FileCloser> file(std::fopen(name.c_str(), "rb"));
  if (!file) return file_error(name, errno != 0 ? errno : EIO);
  std::string text;
  char buffer[16 * 1024];
  std::size_t n = 0;
  // Never more than the limit plus one byte (a FIFO or /dev/zero never ends).
  while (text.size() <= kMaxFileBytes &&
         (n = std::fread(buffer, 1, sizeof buffer, file.get())) > 0) {
    text.append(buffer, n);
  }
  if (std::ferror(file.get())) return file_error(name, errno != 0 ? errno : EIO);
  if (text.size() > kMaxFileBytes) {
    return vigil::unexpected<ConfigErrors>(ConfigErrors{{name, 0, 0, "", too_large()}});
  }
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
  ConfigErrors all = NodeAccess::document(root).errors;
  const std::size_t suppressed = NodeAccess::document(root).suppressed;
  all.insert(all.end(), std::make_move_iterator(loader_errors.begin()),
             std::make_move_iterator(loader_errors.end()));
  if (failed && all.empty() && suppressed == 0) {
    all.push_back({root.file(), 0, 0, "", "the loader rejected the document without saying why"});
  }
  tidy_errors(all, suppressed);
  return all;
}

}  // namespace detail

}  // namespace vigil::config
