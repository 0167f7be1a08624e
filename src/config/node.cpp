#include "vigil/config/node.hpp"

#include "config/document.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>

namespace vigil::config {

namespace detail {

void Document::add(ConfigError error) {
  // Accessors may meet the same problem more than once (two keys read under one bad node).
  if (std::find(errors.begin(), errors.end(), error) != errors.end()) return;
  if (errors.size() >= kMaxErrorsKept) {
    ++suppressed;
    return;
  }
  errors.push_back(std::move(error));
}

ConfigError more_errors(const std::string& file, std::size_t more) {
  return {file, 0, 0, "",
          fmt::format("{} more error{} not listed (only the first {} are)", more,
                      more == 1 ? "" : "s", kMaxErrorsKept)};
}

void tidy_errors(ConfigErrors& errors, std::size_t already_suppressed) {
  std::stable_sort(errors.begin(), errors.end(), [](const ConfigError& a, const ConfigError& b) {
    return std::pair(a.line, a.column) < std::pair(b.line, b.column);
  });
  // Equal errors have equal locations: compare each with the others at its location only.
  ConfigErrors kept;
  std::size_t group = 0;  // index in `kept` where the current location starts
  std::size_t dropped = already_suppressed;
  std::string file = errors.empty() ? std::string() : errors.front().file;
  for (ConfigError& e : errors) {
    if (group < kept.size() &&
        std::pair(kept[group].line, kept[group].column) != std::pair(e.line, e.column)) {
      group = kept.size();
    }
    if (std::find(kept.begin() + static_cast<std::ptrdiff_t>(group), kept.end(), e) != kept.end()) {
      continue;
    }
    if (kept.size() >= kMaxErrorsKept) {
      ++dropped;
      continue;
    }
    kept.push_back(std::move(e));
  }
  if (dropped > 0) kept.push_back(more_errors(file, dropped));
  errors = std::move(kept);
}

std::shared_ptr<Document> NodeAccess::make_document(std::string file, std::string text) {
  return std::make_shared<Document>(std::move(file), std::move(text));
}

std::pair<int, int> NodeAccess::locate(const Document& doc, const YAML::Mark& mark) {
  return doc.locate(mark);
}

Node NodeAccess::make_root(std::shared_ptr<Document> doc, const YAML::Node& root) {
  const auto [line, column] = doc->locate(root.Mark());
  return Node(std::move(doc), root, std::string(), line, column, Node::State::Present);
}

const Document& NodeAccess::document(const Node& node) { return *node.doc_; }

std::pair<int, int> NodeAccess::text_location(const Node& node, const YAML::Mark& mark) {
  return node.doc_->locate(mark);
}

}  // namespace detail

namespace {

std::string join(std::string_view path, std::string_view key) {
  if (path.empty()) return std::string(key);
  std::string out;
  out.reserve(path.size() + 1 + key.size());
  out += path;
  out += '.';
  out += key;
  return out;
}

// A scalar as it appears in a message: quoted, and cut (on a character boundary) if long.
std::string quote(std::string_view s) {
  constexpr std::size_t kMax = 40;
  if (s.size() <= kMax) return fmt::format("'{}'", s);
  std::size_t cut = kMax;
  while (cut > 0 && (static_cast<unsigned char>(s[cut]) & 0xC0) == 0x80) --cut;
  return fmt::format("'{}...'", s.substr(0, cut));
}

std::string describe(const YAML::Node& n) {
  if (n.IsScalar()) return quote(n.Scalar());
  if (n.IsMap()) return "a mapping";
  if (n.IsSequence()) return "a sequence";
  return "an empty value";
}

std::string list_names(std::span<const std::string_view> names, std::string_view last_sep) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += i + 1 == names.size() ? last_sep : ", ";
    out += names[i];
  }
  return out;
}

std::string key_error(const YAML::Node& key) {
  return fmt::format("a key must be a name, got {}", describe(key));
}

// Sign and magnitude of "[+-](digits|0xhex)"; nullopt for anything else. `overflow` is set when
// the magnitude does not fit in 64 bits.
struct Integer {
  bool negative = false;
  std::uint64_t magnitude = 0;
  bool overflow = false;
};

std::optional<Integer> parse_integer(std::string_view text) {
  Integer v;
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
    v.negative = text.front() == '-';
    text.remove_prefix(1);
  }
  int base = 10;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  if (text.empty()) return std::nullopt;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v.magnitude, base);
  if (ptr != end) {
    return std::nullopt;
  }
  v.overflow = ec == std::errc::result_out_of_range;
  if (ec != std::errc() && !v.overflow) return std::nullopt;
  return v;
}

}  // namespace

Node::Node() : doc_(std::make_shared<detail::Document>()), yaml_(YAML::NodeType::Null) {}

Node::Node(std::shared_ptr<detail::Document> doc, const YAML::Node& yaml, std::string path,
           int line, int column, State state)
    : doc_(std::move(doc)),
      yaml_(yaml),
      path_(std::move(path)),
      line_(line),
      column_(column),
      state_(state) {}

// --- navigation ----------------------------------------------------------------------------------

namespace {
// Where errors about a mapping's value point: at the value, except for an empty value
// (`key:`), which yaml-cpp marks at the next token, often lines below: then at the key.
std::pair<int, int> value_location(const detail::Document& doc, const YAML::Node& key,
                                   const YAML::Node& value) {
  const YAML::Mark v = value.Mark();
  if (value.IsNull() && (v.is_null() || v.line != key.Mark().line)) {
    return doc.locate(key.Mark());
  }
  return doc.locate(v);
}
}  // namespace

Node Node::operator[](std::string_view key) const {
  std::string child_path = join(path_, key);
  if (state_ != State::Present) {
    return Node(doc_, YAML::Node(), std::move(child_path), line_, column_, state_);
  }
  if (yaml_.IsNull()) {
    return Node(doc_, YAML::Node(), std::move(child_path), line_, column_, State::Missing);
  }
  if (!yaml_.IsMap()) {
    fail_value_("expected a mapping");
    return Node(doc_, YAML::Node(), std::move(child_path), line_, column_, State::Unreachable);
  }
  // yaml-cpp's operator-> returns a temporary proxy: bind each pair by value (range-for does).
  for (const auto& pair : yaml_) {
    const YAML::Node& k = pair.first;
    if (k.IsScalar() && k.Scalar() == key) {
      const auto [line, column] = value_location(*doc_, k, pair.second);
      return Node(doc_, pair.second, std::move(child_path), line, column, State::Present);
    }
  }
  return Node(doc_, YAML::Node(), std::move(child_path), line_, column_, State::Missing);
}

Node Node::at(std::string_view key) const {
  Node child = (*this)[key];
  if (child.state_ == State::Missing) {
    (void)child.present_or_report_();
    child.state_ = State::Unreachable;
  }
  return child;
}

std::vector<std::pair<std::string, Node>> Node::entries() const {
  std::vector<std::pair<std::string, Node>> out;
  if (state_ != State::Present || yaml_.IsNull()) return out;
  if (!yaml_.IsMap()) {
    fail_value_("expected a mapping");
    return out;
  }
  out.reserve(yaml_.size());
  for (const auto& pair : yaml_) {
    const YAML::Node& k = pair.first;
    if (!k.IsScalar()) {
      const auto [line, column] = doc_->locate(k.Mark());
      doc_->add({doc_->file, line, column, path_, key_error(k)});
      continue;
    }
    const auto [line, column] = value_location(*doc_, k, pair.second);
    out.emplace_back(
        k.Scalar(), Node(doc_, pair.second, join(path_, k.Scalar()), line, column, State::Present));
  }
  return out;
}

std::vector<Node> Node::elements() const {
  std::vector<Node> out;
  if (state_ != State::Present || yaml_.IsNull()) return out;
  if (!yaml_.IsSequence()) {
    fail_value_("expected a sequence");
    return out;
  }
  out.reserve(yaml_.size());
  std::size_t index = 0;
  for (const auto& item : yaml_) {
    auto [line, column] = doc_->locate(item.Mark());
    if (line == 0) std::tie(line, column) = std::pair(line_, column_);
    out.push_back(
        Node(doc_, item, fmt::format("{}[{}]", path_, index++), line, column, State::Present));
  }
  return out;
}

// --- inspection ----------------------------------------------------------------------------------

bool Node::defined() const noexcept { return state_ == State::Present; }

bool Node::has(std::string_view key) const {
  if (!is_mapping()) return false;
  for (const auto& pair : yaml_) {
    if (pair.first.IsScalar() && pair.first.Scalar() == key) return true;
  }
  return false;
}

bool Node::is_null() const { return defined() && yaml_.IsNull(); }
bool Node::is_scalar() const { return defined() && yaml_.IsScalar(); }
bool Node::is_mapping() const { return defined() && yaml_.IsMap(); }
bool Node::is_sequence() const { return defined() && yaml_.IsSequence(); }
const std::string& Node::path() const noexcept { return path_; }
const std::string& Node::file() const noexcept { return doc_->file; }

// --- errors --------------------------------------------------------------------------------------

bool Node::present_or_report_() const {
  switch (state_) {
    case State::Present:
      return true;
    case State::Missing:
      fail_("required key is missing");
      return false;
    case State::Unreachable:
      return false;
  }
  return false;
}

void Node::fail_(std::string message) const {
  doc_->add({doc_->file, line_, column_, path_, std::move(message)});
}

void Node::fail_value_(std::string_view requirement) const {
  fail_(fmt::format("{}, got {}", requirement, describe(yaml_)));
}

void Node::error(std::string message) const { fail_(std::move(message)); }

bool Node::has_errors() const noexcept { return !doc_->errors.empty(); }

ConfigErrors Node::errors() const {
  ConfigErrors out = doc_->errors;
  std::stable_sort(out.begin(), out.end(), [](const ConfigError& a, const ConfigError& b) {
    return std::pair(a.line, a.column) < std::pair(b.line, b.column);
  });
  if (doc_->suppressed > 0) out.push_back(detail::more_errors(doc_->file, doc_->suppressed));
  return out;
}

void Node::reject_unknown_keys_(std::span<const std::string_view> allowed) const {
  if (state_ != State::Present || yaml_.IsNull()) return;
  if (!yaml_.IsMap()) {
    fail_value_("expected a mapping");
    return;
  }
  for (const auto& pair : yaml_) {
    const YAML::Node& k = pair.first;
    const auto [line, column] = doc_->locate(k.Mark());
    if (!k.IsScalar()) {
      doc_->add({doc_->file, line, column, path_, key_error(k)});
      continue;
    }
    const std::string& key = k.Scalar();
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    std::string message = "unknown key";
    if (std::optional<std::string_view> hint = closest_match(key, allowed)) {
      message += fmt::format("; did you mean '{}'?", *hint);
    } else if (allowed.empty()) {
      message += "; this mapping takes no keys";
    } else {
      message += fmt::format("; expected one of: {}", list_names(allowed, ", "));
    }
    doc_->add({doc_->file, line, column, join(path_, key), std::move(message)});
  }
}

// --- conversions ---------------------------------------------------------------------------------

bool Node::convert_bool_(bool& out) const {
  if (yaml_.IsScalar()) {
    const std::string& s = yaml_.Scalar();
    if (s == "true" || s == "True" || s == "TRUE") {
      out = true;
      return true;
    }
    if (s == "false" || s == "False" || s == "FALSE") {
      out = false;
      return true;
    }
  }
  fail_value_("expected true or false");
  return false;
}

bool Node::convert_signed_(std::int64_t& out, std::int64_t min, std::int64_t max) const {
  const std::optional<Integer> v =
      yaml_.IsScalar() ? parse_integer(yaml_.Scalar()) : std::optional<Integer>();
  if (!v) {
    fail_value_("expected an integer");
    return false;
  }
  // |INT64_MIN| = INT64_MAX + 1: compare magnitudes as unsigned.
  const std::uint64_t limit =
      v->negative ? static_cast<std::uint64_t>(-(min + 1)) + 1 : static_cast<std::uint64_t>(max);
  if (v->overflow || v->magnitude > limit) {
    fail_value_(fmt::format("expected an integer between {} and {}", min, max));
    return false;
  }
  out = v->negative && v->magnitude != 0 ? -static_cast<std::int64_t>(v->magnitude - 1) - 1
                                         : static_cast<std::int64_t>(v->magnitude);
  return true;
}

bool Node::convert_unsigned_(std::uint64_t& out, std::uint64_t max) const {
  const std::optional<Integer> v =
      yaml_.IsScalar() ? parse_integer(yaml_.Scalar()) : std::optional<Integer>();
  if (!v) {
    fail_value_("expected an integer");
    return false;
  }
  if (v->overflow || v->magnitude > max || (v->negative && v->magnitude != 0)) {
    fail_value_(fmt::format("expected an integer between 0 and {}", max));
    return false;
  }
  out = v->magnitude;
  return true;
}

bool Node::convert_floating_(double& out, bool to_float) const {
  if (!yaml_.IsScalar()) {
    fail_value_("expected a number");
    return false;
  }
  std::string_view s = yaml_.Scalar();
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0;
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, v);
  if (s.empty() || ptr != end || (ec != std::errc() && ec != std::errc::result_out_of_range)) {
    fail_value_("expected a number");
    return false;
  }
  if (ec == std::errc::result_out_of_range || !std::isfinite(v) ||
      (to_float && std::abs(v) > static_cast<double>(std::numeric_limits<float>::max()))) {
    fail_value_(to_float ? "expected a finite number within float range"
                         : "expected a finite number");
    return false;
  }
  out = v;
  return true;
}

bool Node::convert_string_(std::string& out) const {
  if (!yaml_.IsScalar()) {
    fail_value_("expected a string");
    return false;
  }
  out = yaml_.Scalar();
  return true;
}

bool Node::convert_time_(Nanos& out, bool period, TimeUnit bare_unit) const {
  if (!yaml_.IsScalar()) {
    fail_value_(period ? "expected a period such as '1ms' or '1kHz'"
                       : "expected a duration such as '2.5ms'");
    return false;
  }
  const expected<Nanos, std::string> v =
      period ? parse_period(yaml_.Scalar(), bare_unit) : parse_duration(yaml_.Scalar(), bare_unit);
  if (!v.has_value()) {
    fail_(v.error());
    return false;
  }
  out = *v;
  return true;
}

std::optional<std::size_t> Node::match_name_(std::span<const std::string_view> names) const {
  if (!yaml_.IsScalar()) {
    fail_value_(fmt::format("expected one of {}", list_names(names, " or ")));
    return std::nullopt;
  }
  const std::string& s = yaml_.Scalar();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == s) return i;
  }
  std::string message = fmt::format("{} is not one of {}", quote(s), list_names(names, ", "));
  if (std::optional<std::string_view> hint = closest_match(s, names)) {
    message += fmt::format("; did you mean '{}'?", *hint);
  }
  fail_(std::move(message));
  return std::nullopt;
}

}  // namespace vigil::config
