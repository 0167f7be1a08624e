#include "config/screen.hpp"

#include <fmt/format.h>
#include <yaml-cpp/eventhandler.h>

#include <cstdint>
#include <sstream>
#include <vector>

#include "vigil/config/load.hpp"

namespace vigil::config::detail {
namespace {

struct Stop {
  Refusal refusal;
};

class Screen final : public YAML::EventHandler {
 public:
  explicit Screen(std::string_view text) : text_(text) {}

  void OnDocumentStart(const YAML::Mark& mark) override {
    ++documents_;
    if (documents_ == 1) first_document_ = mark;
  }
  void OnDocumentEnd() override {}

  void OnNull(const YAML::Mark& mark, YAML::anchor_t anchor) override { leaf(mark, anchor); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor,
                const std::string&) override {
    leaf(mark, anchor);
  }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t anchor) override {
    node(mark);
    if (anchor >= anchors_.size() || anchors_[anchor].open) {
      stop(mark, fmt::format("alias {} refers to a node that contains it: a recursive alias "
                             "cannot be expanded",
                             alias_text(mark)));
    }
    const std::uint64_t size = anchors_[anchor].size;
    alias_added_ += size - 1;
    if (alias_added_ > kMaxAliasExpansion) {
      stop(mark, fmt::format("aliases expand to more than {} values in all (an alias bomb?); "
                             "alias {} stands for {} values",
                             kMaxAliasExpansion, alias_text(mark), size));
    }
    add_to_parent(size);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor,
                       YAML::EmitterStyle::value) override {
    open(mark, anchor);
  }
  void OnSequenceEnd() override { close(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor,
                  YAML::EmitterStyle::value) override {
    open(mark, anchor);
  }
  void OnMapEnd() override { close(); }
  void OnAnchor(const YAML::Mark&, const std::string&) override {}

  [[nodiscard]] int documents() const { return documents_; }

 private:
  struct Anchor {
    std::uint64_t size = 1;  // values the anchored node stands for, aliases expanded
    bool open = false;       // still being parsed: an alias to it is a cycle
  };
  struct Open {
    YAML::anchor_t anchor = 0;
    std::uint64_t size = 1;
  };

  [[noreturn]] static void stop(const YAML::Mark& mark, std::string message) {
    throw Stop{Refusal{mark, std::move(message)}};
  }

  // "*name" as written at `mark` (the alias token), for messages.
  [[nodiscard]] std::string alias_text(const YAML::Mark& mark) const {
    if (mark.pos < 0 || static_cast<std::size_t>(mark.pos) >= text_.size()) return "(alias)";
    const std::string_view rest = text_.substr(static_cast<std::size_t>(mark.pos));
    std::size_t n = 0;
    while (n < rest.size() && n < 64 && rest[n] != ' ' && rest[n] != '\t' && rest[n] != '\n' &&
           rest[n] != '\r' && rest[n] != ',' && rest[n] != ']' && rest[n] != '}') {
      ++n;
    }
    return std::string(rest.substr(0, n));
  }

  // Every value of the document goes through here first.
  void node(const YAML::Mark& mark) {
    if (documents_ > 1) second_document(mark);
    if (++nodes_ > kMaxNodes) {
      stop(mark, fmt::format("more than {} values in one file (the limit of a configuration "
                             "file)",
                             kMaxNodes));
    }
  }

  void second_document(const YAML::Mark& mark) {
    const bool in_text = mark.pos >= 0 && static_cast<std::size_t>(mark.pos) < text_.size();
    if (in_text && text_[static_cast<std::size_t>(mark.pos)] == ',') {
      stop(mark, "unexpected ',' outside a flow sequence [...] or mapping {...}");
    }
    if (mark.pos == first_document_.pos) {
      // yaml-cpp started a document without consuming anything: it would do so forever.
      stop(mark, in_text ? fmt::format("cannot parse from here (unexpected '{}')",
                                       text_[static_cast<std::size_t>(mark.pos)])
                         : std::string("cannot parse from here"));
    }
    stop(mark, "a file must hold a single YAML document; a second one starts here");
  }

  void leaf(const YAML::Mark& mark, YAML::anchor_t anchor) {
    node(mark);
    if (anchor != 0) anchor_at(anchor) = Anchor{1, false};
    add_to_parent(1);
  }

  void open(const YAML::Mark& mark, YAML::anchor_t anchor) {
    node(mark);
    if (stack_.size() >= static_cast<std::size_t>(kMaxNestingDepth)) {
      stop(mark, fmt::format("nesting deeper than {} levels (mappings and sequences inside each "
                             "other): the limit of a configuration file",
                             kMaxNestingDepth));
    }
    if (anchor != 0) anchor_at(anchor) = Anchor{1, true};
    stack_.push_back({anchor, 1});
  }

  void close() {
    if (stack_.empty()) return;
    const Open top = stack_.back();
    stack_.pop_back();
    if (top.anchor != 0) anchor_at(top.anchor) = Anchor{top.size, false};
    add_to_parent(top.size);
  }

  void add_to_parent(std::uint64_t size) {
    if (!stack_.empty()) stack_.back().size += size;
  }

  Anchor& anchor_at(YAML::anchor_t anchor) {
    if (anchor >= anchors_.size()) anchors_.resize(anchor + 1);
    return anchors_[anchor];
  }

  std::string_view text_;
  int documents_ = 0;
  YAML::Mark first_document_ = YAML::Mark::null_mark();
  std::size_t nodes_ = 0;
  std::uint64_t alias_added_ = 0;
  std::vector<Open> stack_;
  std::vector<Anchor> anchors_;  // by yaml-cpp's anchor id (1, 2, ... per document)
};

}  // namespace

std::optional<Refusal> screen_yaml(std::string_view text) {
  std::istringstream in{std::string(text)};
  YAML::Parser parser(in);
  Screen screen(text);
  try {
    // At most two documents: the second one is refused at its first value, so the loop ends
    // even where yaml-cpp would produce empty documents forever.
    for (int i = 0; i < 2 && parser.HandleNextDocument(screen); ++i) {
    }
  } catch (Stop& s) {
    return std::move(s.refusal);
  }
  return std::nullopt;
}

}  // namespace vigil::config::detail
