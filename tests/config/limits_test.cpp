// Hostile and huge configuration files: every one is refused (or loaded) in bounded time and
// memory, with an error saying what is wrong and where. Each case is a regression test for a
// problem found by fuzzing or by hand (issue 20).
#include <catch2/catch.hpp>
#include <string>

#include "vigil/config/load.hpp"

using namespace vigil::config;

namespace {

const std::string kHostile = std::string(VIGIL_CONFIG_TEST_DATA) + "/hostile/";

// The single error of a refused load.
ConfigError only_error(const vigil::expected<Node, ConfigErrors>& r) {
  REQUIRE_FALSE(r.has_value());
  REQUIRE(r.error().size() == 1);
  return r.error().front();
}

}  // namespace

TEST_CASE("A file holding only ',' is refused where it is, not parsed forever",
          "[config][limits]") {
  // yaml-cpp 0.7.0's LoadAll returns empty documents forever on it (yaml-cpp issue 1040).
  const std::string kMessage = "unexpected ',' outside a flow sequence [...] or mapping {...}";
  CHECK(only_error(load_string(",", "c.yaml")) == ConfigError{"c.yaml", 1, 1, "", kMessage});
  CHECK(only_error(load_string("a: 1\n,\n", "c.yaml")) ==
        ConfigError{"c.yaml", 2, 1, "", "end of map not found"});
  CHECK(only_error(load_string("- x\n, y\n", "c.yaml")) ==
        ConfigError{"c.yaml", 2, 1, "", kMessage});
  CHECK(only_error(load_file(kHostile + "comma.yaml")) ==
        ConfigError{kHostile + "comma.yaml", 1, 1, "", kMessage});
  // Inside a flow collection a ',' is what it should be.
  CHECK(load_string("[1, 2]", "ok.yaml").has_value());
}

TEST_CASE("An alias bomb is refused at the alias that passes the limit", "[config][limits]") {
  const ConfigError e = only_error(load_file(kHostile + "alias_bomb.yaml"));
  // {ids: [1]} is 4 values; each level is a mapping, its key, a list and 10 aliases of the level
  // before: &e stands for 43,333. The aliases of levels b-e add 48,090 in all; the second *e
  // (line 9, column 21) passes 100,000.
  CHECK(e.file == kHostile + "alias_bomb.yaml");
  CHECK(e.line == 9);
  CHECK(e.column == 21);
  CHECK(e.message ==
        "aliases expand to more than 100000 values in all (an alias bomb?); alias *e stands for "
        "43333 values");
}

TEST_CASE("Aliases within the limit still load and read as the anchored value",
          "[config][limits]") {
  const auto shared = load_string("base: &b {x: 1}\nother: *b\n", "a.yaml");
  REQUIRE(shared.has_value());
  CHECK((*shared)["other"].required<int>("x") == 1);
  // 1,000 aliases to a 10-value list: 10,000 values added, under the limit.
  std::string text = "base: &b [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]\nuses: [";
  for (int i = 0; i < 1000; ++i) text += i == 0 ? "*b" : ", *b";
  text += "]\n";
  const auto many = load_string(text, "m.yaml");
  REQUIRE(many.has_value());
  CHECK((*many)["uses"].elements().size() == 1000);
}

TEST_CASE("A recursive alias is refused: a walk of it would never end", "[config][limits]") {
  CHECK(only_error(load_string("a: &x [1, *x]\n", "c.yaml")) ==
        ConfigError{"c.yaml", 1, 11, "",
                    "alias *x refers to a node that contains it: a recursive alias cannot be "
                    "expanded"});
  const ConfigError e = only_error(load_file(kHostile + "recursive_alias.yaml"));
  CHECK(e.line == 2);
  CHECK(e.column == 18);
  CHECK(e.message.find("alias *f refers to a node that contains it") == 0);
}

TEST_CASE("Nesting deeper than 100 levels is refused where it passes the limit",
          "[config][limits]") {
  const std::string kMessage =
      "nesting deeper than 100 levels (mappings and sequences inside each other): the limit of a "
      "configuration file";
  // 100 levels load; the 101st '[' is refused (yaml-cpp alone says "bad file" at 2,000).
  CHECK(load_string(std::string(100, '[') + std::string(100, ']'), "d.yaml").has_value());
  CHECK(only_error(load_string(std::string(101, '[') + std::string(101, ']'), "d.yaml")) ==
        ConfigError{"d.yaml", 1, 101, "", kMessage});
  // Unclosed, yaml-cpp reads each inner '[' as the key of a mapping: 2 levels per '['.
  CHECK(only_error(load_string(std::string(5000, '['), "d.yaml")) ==
        ConfigError{"d.yaml", 1, 51, "", kMessage});
  // Block mappings, one level per line: level 101 is on line 101.
  std::string block;
  for (int i = 0; i < 1000; ++i) block += std::string(static_cast<std::size_t>(i), ' ') + "a:\n";
  CHECK(only_error(load_string(block, "b.yaml")) == ConfigError{"b.yaml", 101, 101, "", kMessage});
  const ConfigError e = only_error(load_file(kHostile + "deep_flow.yaml"));
  CHECK(e.line == 1);
  CHECK(e.message == kMessage);
}

TEST_CASE("A one-line flow mapping of 100,000 entries loads, and its errors are located exactly",
          "[config][limits]") {
  // Locating a node rescanned its line: quadratic, tens of seconds for this file (1.3 MB).
  // Now O(log lines) per node; the CTest timeout catches a return to quadratic time.
  std::string text = "{";
  for (int i = 0; i < 100'000; ++i)
    text += "k" + std::to_string(i) + ": " + std::to_string(i) + ", ";
  const std::size_t duplicate_column = text.size() + 1;
  text += "k7: 1}";
  const ConfigError e = only_error(load_string(text, "wide.yaml"));
  CHECK(e == ConfigError{"wide.yaml", 1, static_cast<int>(duplicate_column), "k7",
                         "duplicate key (first defined at line 1, column 51)"});
  // The same with multi-byte characters before it: columns count characters, not bytes.
  std::string utf8 = "{";
  std::size_t chars = 1;
  for (int i = 0; i < 50'000; ++i) {
    const std::string key = "é" + std::to_string(i);
    utf8 += key + ": 1, ";
    chars += 1 + std::to_string(i).size() + 5;
  }
  utf8 += "é3: 2}";
  const ConfigError u = only_error(load_string(utf8, "utf8.yaml"));
  CHECK(u.line == 1);
  CHECK(u.column == static_cast<int>(chars + 1));
  // Without the duplicate, every entry is there.
  text.replace(text.size() - 6, 6, "}");
  const auto ok = load_string(text, "wide.yaml");
  REQUIRE(ok.has_value());
  CHECK(ok->entries().size() == 100'000);
}

TEST_CASE("A file of more than 500,000 values is refused", "[config][limits]") {
  std::string text = "[";
  for (int i = 0; i < 500'001; ++i) text += "0,";
  text += "0]";
  const ConfigError e = only_error(load_string(text, "n.yaml"));
  CHECK(e.line == 1);
  CHECK(e.column == 2 * 500'000);  // the 500,001st value (the list is the first)
  CHECK(e.message == "more than 500000 values in one file (the limit of a configuration file)");
}

TEST_CASE("A file larger than 4 MiB is refused before it is parsed, even one that never ends",
          "[config][limits]") {
  const std::string big(kMaxFileBytes + 1, '#');
  CHECK(only_error(load_string(big, "big.yaml")) ==
        ConfigError{"big.yaml", 0, 0, "", "file is larger than 4 MiB: not a configuration file"});
  CHECK(load_string(std::string(kMaxFileBytes, '#'), "max.yaml").has_value());
  // /dev/zero has no end: reading stops at the limit.
  CHECK(only_error(load_file("/dev/zero")) ==
        ConfigError{"/dev/zero", 0, 0, "", "file is larger than 4 MiB: not a configuration file"});
}

TEST_CASE("At most 100 errors are listed, then how many more there were", "[config][limits]") {
  std::string text;
  for (int i = 0; i < 1000; ++i) text += "a: " + std::to_string(i) + "\n";
  const auto dup = load_string(text, "dup.yaml");
  REQUIRE_FALSE(dup.has_value());
  REQUIRE(dup.error().size() == 101);
  CHECK(dup.error()[99].line == 101);
  CHECK(dup.error()[100] ==
        ConfigError{"dup.yaml", 0, 0, "", "899 more errors not listed (only the first 100 are)"});

  // Errors recorded by a loader through Node, and its own, are capped the same way.
  std::string list = "v: [";
  for (int i = 0; i < 1000; ++i) list += i == 0 ? "x" : ", x";
  list += "]\n";
  const auto r = load_string(list, "l.yaml", [](const Node& root) {
    ConfigErrors own;
    for (int i = 0; i < 500; ++i) own.push_back({"l.yaml", 2, i + 1, "own", "mine"});
    for (const Node& item : root["v"].elements()) (void)item.get<int>();
    return vigil::expected<int, ConfigErrors>(vigil::unexpected<ConfigErrors>(std::move(own)));
  });
  REQUIRE_FALSE(r.has_value());
  REQUIRE(r.error().size() == 101);
  CHECK(r.error()[100].message == "1400 more errors not listed (only the first 100 are)");
}

TEST_CASE("A value of a megabyte gets no did-you-mean hint, quickly", "[config][limits]") {
  // The hint's edit distance is O(n*m): skipped when the lengths alone are too far apart.
  enum class Policy { Fifo, Other };
  const std::string value(1 << 20, 'F');
  const auto r = load_string("policy: " + value + "\n", "k.yaml", [](const Node& root) {
    return root.required_enum<Policy>("policy", {{"FIFO", Policy::Fifo}, {"OTHER", Policy::Other}});
  });
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error()[0].message.find("did you mean") == std::string::npos);
  CHECK(r.error()[0].line == 1);
  CHECK(r.error()[0].column == 9);
}
