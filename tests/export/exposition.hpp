#pragma once
// A strict reader of the Prometheus 0.0.4 / OpenMetrics text formats for the export tests: it
// throws on any line it cannot read, and groups samples by family as the formats define them.
#include <cmath>
#include <cstdlib>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace vigil::test {

struct Sample {
  std::string name;
  std::vector<std::pair<std::string, std::string>> labels;  // unescaped values
  std::string value_text;
  double value = 0;

  [[nodiscard]] std::string label(std::string_view n) const {
    for (const auto& [k, v] : labels) {
      if (k == n) return v;
    }
    return {};
  }
};

struct Family {
  std::string name;  // as in the TYPE line
  std::string type;
  std::string help;  // unescaped
  bool has_help = false;
  bool has_type = false;
  std::string unit;
  std::vector<Sample> samples;
};

struct Exposition {
  std::vector<Family> families;  // in order
  bool eof = false;

  [[nodiscard]] const Family* find(std::string_view name) const {
    for (const auto& f : families) {
      if (f.name == name) return &f;
    }
    return nullptr;
  }
};

inline std::string unescape(std::string_view s, bool quotes) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '\\') {
      out += s[i];
      continue;
    }
    if (++i >= s.size()) throw std::runtime_error("dangling backslash");
    if (s[i] == 'n') {
      out += '\n';
    } else if (s[i] == '\\') {
      out += '\\';
    } else if (s[i] == '"' && quotes) {
      out += '"';
    } else {
      throw std::runtime_error(std::string("bad escape \\") + s[i]);
    }
  }
  return out;
}

// Which family a sample belongs to, given the declared families.
inline bool belongs(const Family& f, std::string_view sample, bool om) {
  const auto is = [&](std::string_view suffix) { return sample == f.name + std::string(suffix); };
  if (f.type == "histogram") return is("_bucket") || is("_sum") || is("_count");
  if (f.type == "summary") return is("") || is("_sum") || is("_count");
  if (f.type == "counter") return om ? is("_total") : is("");
  if (f.type == "info") return is("_info");
  return is("");
}

inline Exposition parse_exposition(const std::string& text, bool om) {
  Exposition e;
  std::size_t pos = 0;
  int line_no = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) throw std::runtime_error("last line has no newline");
    const std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const auto fail = [&](const std::string& why) {
      throw std::runtime_error("line " + std::to_string(line_no) + ": " + why + ": " + line);
    };
    if (e.eof) fail("line after # EOF");
    if (line.empty()) fail("empty line");
    if (line == "# EOF") {
      e.eof = true;
      continue;
    }
    if (line.rfind("# ", 0) == 0) {
      const std::size_t sp1 = line.find(' ', 2);
      if (sp1 == std::string::npos) fail("short comment");
      const std::string kw = line.substr(2, sp1 - 2);
      const std::size_t sp2 = line.find(' ', sp1 + 1);
      const std::string name = line.substr(sp1 + 1, sp2 == std::string::npos ? sp2 : sp2 - sp1 - 1);
      const std::string rest = sp2 == std::string::npos ? "" : line.substr(sp2 + 1);
      if (e.families.empty() || e.families.back().name != name) {
        if (e.find(name) != nullptr) fail("family declared twice (not contiguous)");
        if (!e.families.empty() && e.families.back().samples.empty()) {
          fail("family " + e.families.back().name + " has no sample");
        }
        e.families.emplace_back();
        e.families.back().name = name;
      }
      Family& f = e.families.back();
      if (kw == "HELP") {
        if (f.has_help) fail("second HELP");
        f.help = unescape(rest, om);
        f.has_help = true;
      } else if (kw == "TYPE") {
        if (f.has_type) fail("second TYPE");
        f.type = rest;
        f.has_type = true;
      } else if (kw == "UNIT") {
        f.unit = rest;
      } else {
        fail("unknown comment");
      }
      continue;
    }
    // A sample: name{labels} value
    Sample s;
    std::size_t i = 0;
    while (i < line.size() && line[i] != '{' && line[i] != ' ') ++i;
    s.name = line.substr(0, i);
    if (i < line.size() && line[i] == '{') {
      ++i;
      while (true) {
        const std::size_t eq = line.find('=', i);
        if (eq == std::string::npos || line[eq + 1] != '"') fail("bad label");
        const std::string key = line.substr(i, eq - i);
        std::size_t j = eq + 2;
        std::string raw;
        while (j < line.size() && line[j] != '"') {
          if (line[j] == '\\') raw += line[j++];
          if (j < line.size()) raw += line[j++];
        }
        if (j >= line.size()) fail("unterminated label value");
        s.labels.emplace_back(key, unescape(raw, true));
        i = j + 1;
        if (line[i] == ',') {
          ++i;
          continue;
        }
        if (line[i] == '}') {
          ++i;
          break;
        }
        fail("bad label separator");
      }
    }
    if (i >= line.size() || line[i] != ' ') fail("no value");
    s.value_text = line.substr(i + 1);
    if (s.value_text == "+Inf") {
      s.value = INFINITY;
    } else if (s.value_text == "-Inf") {
      s.value = -INFINITY;
    } else if (s.value_text == "NaN") {
      s.value = NAN;
    } else {
      char* endp = nullptr;
      s.value = std::strtod(s.value_text.c_str(), &endp);
      if (endp == nullptr || *endp != '\0' || s.value_text.empty()) fail("bad value");
    }
    if (e.families.empty() || !belongs(e.families.back(), s.name, om)) {
      fail("sample outside its family (or family without TYPE)");
    }
    e.families.back().samples.push_back(std::move(s));
  }
  return e;
}

}  // namespace vigil::test
