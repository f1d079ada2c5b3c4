#include "core/Parameters.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <sstream>

namespace grainwave {

std::string type_name(ParameterType type) {
  switch (type) {
    case ParameterType::kBool: return "bool";
    case ParameterType::kInt: return "integer";
    case ParameterType::kReal: return "real";
    case ParameterType::kString: return "string";
    case ParameterType::kRealArray: return "array of reals";
    case ParameterType::kIntArray: return "array of integers";
    case ParameterType::kStringArray: return "array of strings";
  }
  return "?";
}

namespace {
std::string real_to_toml(double v) {
  if (v == std::numeric_limits<double>::infinity()) return "inf";
  if (v == -std::numeric_limits<double>::infinity()) return "-inf";
  std::string s = fmt::format("{}", v);  // shortest round-trip representation
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}
std::string quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}
template <class T, class F>
std::string join_array(const std::vector<T>& values, F&& format_one) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + format_one(values[i]);
  return out + "]";
}
}  // namespace

std::string to_toml(const ParameterValue& value) {
  struct Visitor {
    std::string operator()(bool b) const { return b ? "true" : "false"; }
    std::string operator()(std::int64_t i) const { return std::to_string(i); }
    std::string operator()(double d) const { return real_to_toml(d); }
    std::string operator()(const std::string& s) const { return quote(s); }
    std::string operator()(const std::vector<double>& a) const { return join_array(a, real_to_toml); }
    std::string operator()(const std::vector<std::int64_t>& a) const {
      return join_array(a, [](std::int64_t i) { return std::to_string(i); });
    }
    std::string operator()(const std::vector<std::string>& a) const { return join_array(a, quote); }
  };
  return std::visit(Visitor{}, value);
}

std::string ParameterDecl::range_text() const {
  if (!choices.empty()) {
    std::string s = "one of: ";
    for (std::size_t i = 0; i < choices.size(); ++i) s += (i ? ", " : "") + choices[i];
    return s;
  }
  std::string s;
  if (lower || upper) {
    s = fmt::format("{}{}, {}{}", lower_open || !lower ? "(" : "[",
                    lower ? fmt::format("{}", *lower) : "-inf",
                    upper ? fmt::format("{}", *upper) : "inf",
                    upper_open || !upper ? ")" : "]");
  }
  if (length > 0) s += (s.empty() ? "" : ", ") + fmt::format("length {}", length);
  return s;
}

namespace {
ParameterDecl& add(SectionDecl& section, std::string key, ParameterType type,
                   std::optional<ParameterValue> def, std::string doc) {
  ParameterDecl d;
  d.key = std::move(key);
  d.type = type;
  d.default_value = std::move(def);
  d.doc = std::move(doc);
  section.parameters.push_back(std::move(d));
  return section.parameters.back();
}
template <class T>
std::optional<ParameterValue> wrap(const std::optional<T>& v) {
  if (!v) return std::nullopt;
  return ParameterValue(*v);
}
}  // namespace

ParameterDecl& SectionDecl::flag(std::string key, std::optional<bool> def, std::string d) {
  return add(*this, std::move(key), ParameterType::kBool, wrap(def), std::move(d));
}
ParameterDecl& SectionDecl::integer(std::string key, std::optional<std::int64_t> def,
                                    std::string d) {
  return add(*this, std::move(key), ParameterType::kInt, wrap(def), std::move(d));
}
ParameterDecl& SectionDecl::real(std::string key, std::optional<double> def, std::string d) {
  return add(*this, std::move(key), ParameterType::kReal, wrap(def), std::move(d));
}
ParameterDecl& SectionDecl::text(std::string key, std::optional<std::string> def, std::string d) {
  return add(*this, std::move(key), ParameterType::kString, wrap(def), std::move(d));
}
ParameterDecl& SectionDecl::reals(std::string key, std::optional<std::vector<double>> def,
                                  std::string d) {
  return add(*this, std::move(key), ParameterType::kRealArray, wrap(def), std::move(d));
}
ParameterDecl& SectionDecl::integers(std::string key,
                                     std::optional<std::vector<std::int64_t>> def, std::string d) {
  return add(*this, std::move(key), ParameterType::kIntArray, wrap(def), std::move(d));
}
ParameterDecl& SectionDecl::texts(std::string key, std::optional<std::vector<std::string>> def,
                                  std::string d) {
  return add(*this, std::move(key), ParameterType::kStringArray, wrap(def), std::move(d));
}

const ParameterDecl* SectionDecl::find(const std::string& key) const {
  for (const auto& p : parameters)
    if (p.key == key) return &p;
  return nullptr;
}

SectionDecl& SceneSchema::section(const std::string& name, const std::string& doc, bool repeated) {
  for (auto& s : sections_)
    if (s.name == name) return s;
  SectionDecl s;
  s.name = name;
  s.doc = doc;
  s.repeated = repeated;
  sections_.push_back(std::move(s));
  return sections_.back();
}

const SectionDecl* SceneSchema::find(const std::string& name) const {
  for (const auto& s : sections_)
    if (s.name == name) return &s;
  return nullptr;
}

std::string SceneSchema::reference_markdown() const {
  std::ostringstream out;
  out << "# Scene file reference\n\n"
      << "Generated from the parameter declarations by `grainwave reference`; do not edit by hand\n"
      << "(the test `scene_reference_up_to_date` fails when this page is stale; regenerate with\n"
      << "`build/app/grainwave reference > docs/scene-reference.md`).\n\n"
      << "A scene is a TOML file. Only the sections it contains are built. Unknown keys, wrong\n"
      << "types and out-of-range values are errors naming the file, line and key. Any key can be\n"
      << "overridden from the command line with `--set section.key=value` (for a repeated\n"
      << "section, `--set section.N.key=value`, N counting from 0).\n";
  for (const auto& s : sections_) {
    out << "\n## " << (s.repeated ? "[[" + s.name + "]]" : "[" + s.name + "]") << "\n\n"
        << s.doc << "\n\n"
        << "| key | type | default | range | meaning |\n| --- | --- | --- | --- | --- |\n";
    for (const auto& p : s.parameters) {
      std::string def = p.default_value ? "`" + to_toml(*p.default_value) + "`" : "**required**";
      std::string range = p.range_text();
      for (auto& c : range)
        if (c == '|') c = '/';
      out << "| `" << p.key << "` | " << type_name(p.type) << " | " << def << " | " << range
          << " | " << p.doc << " |\n";
    }
  }
  return out.str();
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  // Optimal-string-alignment distance: insertions, deletions, substitutions and adjacent
  // transpositions ("tned" for "tend") each count as one edit.
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i)
    for (std::size_t j = 1; j <= m; ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1,
                          d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[n][m];
}

std::optional<std::string> closest_match(const std::string& word,
                                         const std::vector<std::string>& candidates) {
  std::optional<std::string> best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_distance) {
      best_distance = d;
      best = c;
    }
  }
  const std::size_t tolerance = std::max<std::size_t>(2, word.size() / 3);
  if (best && best_distance <= tolerance) return best;
  return std::nullopt;
}

}  // namespace grainwave
