#pragma once
// The first of the two passes that load a YAML document: yaml-cpp's parser runs with an event
// handler that builds nothing and enforces vigil's limits before yaml-cpp builds a node tree.
//
// It refuses, each at the mark where the problem is seen:
//  - nesting deeper than kMaxNestingDepth (yaml-cpp itself stops at 2,000 levels with the
//    message "bad file");
//  - more than kMaxNodes values;
//  - aliases that refer to a node containing them (a cycle: every consumer walking the tree
//    would loop), and aliases that, expanded, add more than kMaxAliasExpansion values (an alias
//    bomb: 512 bytes can stand for billions of values);
//  - a second document, and a ',' outside any flow collection, on which yaml-cpp 0.7.0's
//    YAML::LoadAll loops forever producing empty documents (yaml-cpp issue 1040).
// It stops after the second document at the latest, so it always ends.

#include <string>
#include <string_view>

#include <yaml-cpp/yaml.h>

#include <optional>

namespace vigil::config::detail {

struct Refusal {
  YAML::Mark mark;
  std::string message;
};

/// Runs the first pass over `text`: nullopt when the document may be built, else why not.
/// Throws YAML::Exception on a syntax error (as building would).
[[nodiscard]] std::optional<Refusal> screen_yaml(std::string_view text);

}  // namespace vigil::config::detail
