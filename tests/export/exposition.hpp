#pragma once
// A strict reader of the Prometheus 0.0.4 / OpenMetrics text formats for the export tests: it
// throws on any line it cannot read, and groups samples by family as the formats define them.
#include <cmath>
#include <cstdlib>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace vigil::test {

// An OpenMetrics exemplar: `# {labels} value [timestamp]` after a sample's value.
struct Exemplar {
  std::vector<std::pair<std::string, std::string>> labels;  // unescaped values
  double value = 0;
  std::optional<double> timestamp;

  [[nodiscard]] std::string label(std::string_view n) const {
    for (const auto& [k, v] : labels) {
      if (k == n) return v;
    }
    return {};
  }
};

struct Sample {
  std::string name;
  std::vector<std::pair<std::string, std::string>> labels;  // unescaped values
  std::string value_text;
  double value = 0;
  std::optional<Exemplar> exemplar;

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

// Code points of UTF-8 text (the exemplar's length limit counts them).
inline std::size_t code_points(std::string_view s) {
  std::size_t n = 0;
  for (char c : s) n += (static_cast<unsigned char>(c) & 0xC0U) != 0x80U ? 1 : 0;
  return n;
}

inline bool valid_label_name(std::string_view n) {
  if (n.empty()) return false;
  for (std::size_t i = 0; i < n.size(); ++i) {
    const char c = n[i];
    const bool alpha = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
    if (!alpha && !(i > 0 && c >= '0' && c <= '9')) return false;
  }
  return true;
}

// A number as the formats write it ("+Inf", "-Inf", "NaN" or a decimal); throws otherwise.
inline double parse_number(const std::string& text) {
  if (text == "+Inf") return INFINITY;
  if (text == "-Inf") return -INFINITY;
  if (text == "NaN") return NAN;
  char* endp = nullptr;
  const double v = std::strtod(text.c_str(), &endp);
  if (text.empty() || endp == nullptr || *endp != '\0' || text.find_first_of(" \t") != text.npos) {
    throw std::runtime_error("bad number '" + text + "'");
  }
  return v;
}

// Reads `{name="value",...}` from `line` at `i` (which is at '{'); leaves `i` after the '}'.
// Label names must be valid and unique.
inline std::vector<std::pair<std::string, std::string>> parse_labels(const std::string& line,
                                                                     std::size_t& i);

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
    // A sample: name{labels} value [# {labels} value [timestamp]]
    Sample s;
    std::size_t i = 0;
    while (i < line.size() && line[i] != '{' && line[i] != ' ') ++i;
    s.name = line.substr(0, i);
    try {
      if (i < line.size() && line[i] == '{') s.labels = parse_labels(line, i);
    } catch (const std::runtime_error& err) {
      fail(err.what());
    }
    if (i >= line.size() || line[i] != ' ') fail("no value");
    const std::size_t hash = line.find(" # ", i);
    s.value_text = line.substr(i + 1, hash == std::string::npos ? hash : hash - i - 1);
    try {
      s.value = parse_number(s.value_text);
    } catch (const std::runtime_error&) {
      fail("bad value");
    }
    if (e.families.empty() || !belongs(e.families.back(), s.name, om)) {
      fail("sample outside its family (or family without TYPE)");
    }
    if (hash != std::string::npos) {
      // An exemplar: OpenMetrics only, on a counter's _total or a histogram's _bucket.
      const Family& f = e.families.back();
      if (!om) fail("exemplar in the 0.0.4 text format");
      const bool total = f.type == "counter" && s.name == f.name + "_total";
      const bool bucket = f.type == "histogram" && s.name == f.name + "_bucket";
      if (!total && !bucket) fail("exemplar outside a counter's _total or a histogram's _bucket");
      Exemplar x;
      std::size_t j = hash + 3;
      if (j >= line.size() || line[j] != '{') fail("exemplar without its label set");
      try {
        x.labels = parse_labels(line, j);
      } catch (const std::runtime_error& err) {
        fail(std::string("exemplar: ") + err.what());
      }
      std::size_t length = 0;
      for (const auto& [k, v] : x.labels) length += code_points(k) + code_points(v);
      if (length > 128) fail("exemplar label set longer than 128 code points");
      if (j >= line.size() || line[j] != ' ') fail("exemplar without a value");
      const std::string rest = line.substr(j + 1);
      const std::size_t sp = rest.find(' ');
      try {
        x.value = parse_number(rest.substr(0, sp));
        if (sp != std::string::npos) x.timestamp = parse_number(rest.substr(sp + 1));
      } catch (const std::runtime_error& err) {
        fail(std::string("exemplar: ") + err.what());
      }
      if (std::isnan(x.value)) fail("exemplar value NaN");
      if (x.timestamp && !std::isfinite(*x.timestamp)) fail("exemplar timestamp not finite");
      if (bucket) {
        const std::string le = s.label("le");
        if (le.empty()) fail("bucket without le");
        if (!(x.value <= parse_number(le))) fail("exemplar value above its bucket's le");
      }
      s.exemplar = std::move(x);
    }
    e.families.back().samples.push_back(std::move(s));
  }
  return e;
}

inline std::vector<std::pair<std::string, std::string>> parse_labels(const std::string& line,
                                                                     std::size_t& i) {
  std::vector<std::pair<std::string, std::string>> labels;
  ++i;  // '{'
  if (i < line.size() && line[i] == '}') {
    ++i;
    return labels;
  }
  while (true) {
    const std::size_t eq = line.find('=', i);
    if (eq == std::string::npos || eq + 1 >= line.size() || line[eq + 1] != '"') {
      throw std::runtime_error("bad label");
    }
    const std::string key = line.substr(i, eq - i);
    if (!valid_label_name(key)) throw std::runtime_error("bad label name '" + key + "'");
    for (const auto& l : labels) {
      if (l.first == key) throw std::runtime_error("label '" + key + "' twice");
    }
    std::size_t j = eq + 2;
    std::string raw;
    while (j < line.size() && line[j] != '"') {
      if (line[j] == '\\') raw += line[j++];
      if (j < line.size()) raw += line[j++];
    }
    if (j >= line.size()) throw std::runtime_error("unterminated label value");
    labels.emplace_back(key, unescape(raw, true));
    i = j + 1;
    if (i < line.size() && line[i] == ',') {
      ++i;
      continue;
    }
    if (i < line.size() && line[i] == '}') {
      ++i;
      return labels;
    }
    throw std::runtime_error("bad label separator");
  }
}

}  // namespace vigil::test
