#pragma once
// Declarations of every scene parameter: name, type, default, range, one line of documentation.
// A declaration is written once, by the module that reads the parameter, and it alone drives
// parsing, validation, `grainwave check` output and the generated docs/scene-reference.md.
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace grainwave {

using ParameterValue = std::variant<bool, std::int64_t, double, std::string, std::vector<double>,
                                    std::vector<std::int64_t>, std::vector<std::string>>;

enum class ParameterType { kBool, kInt, kReal, kString, kRealArray, kIntArray, kStringArray };

std::string type_name(ParameterType type);
/// TOML spelling of a value ("1.5", "[0.0, 1.0]", "\"fcc\"").
std::string to_toml(const ParameterValue& value);

struct ParameterDecl {
  std::string key;
  ParameterType type = ParameterType::kReal;
  std::optional<ParameterValue> default_value;  ///< none: the key is required
  std::optional<double> lower, upper;           ///< bounds on numbers and array elements
  bool lower_open = false, upper_open = false;  ///< exclusive bounds
  std::vector<std::string> choices;             ///< allowed strings (empty: any)
  int length = 0;                               ///< exact array length (0: any, non-empty)
  std::string doc;

  // Fluent refinements, used as  section.real("t_end", 1.0, "...").above(0.0)
  ParameterDecl& at_least(double v) { lower = v; lower_open = false; return *this; }
  ParameterDecl& above(double v) { lower = v; lower_open = true; return *this; }
  ParameterDecl& at_most(double v) { upper = v; upper_open = false; return *this; }
  ParameterDecl& below(double v) { upper = v; upper_open = true; return *this; }
  ParameterDecl& in_range(double lo, double hi) { return at_least(lo).at_most(hi); }
  ParameterDecl& one_of(std::vector<std::string> allowed) { choices = std::move(allowed); return *this; }
  ParameterDecl& of_length(int n) { length = n; return *this; }

  bool required() const { return !default_value.has_value(); }
  /// Human-readable range, e.g. "(0, inf)", "one of: fcc, random", "" when unconstrained.
  std::string range_text() const;
};

struct SectionDecl {
  std::string name;
  std::string doc;        ///< what the section builds, one line
  bool repeated = false;  ///< written as [[name]]: a list of entries
  std::deque<ParameterDecl> parameters;  // deque: references stay valid while declaring

  ParameterDecl& flag(std::string key, std::optional<bool> def, std::string doc);
  ParameterDecl& integer(std::string key, std::optional<std::int64_t> def, std::string doc);
  ParameterDecl& real(std::string key, std::optional<double> def, std::string doc);
  ParameterDecl& text(std::string key, std::optional<std::string> def, std::string doc);
  ParameterDecl& reals(std::string key, std::optional<std::vector<double>> def, std::string doc);
  ParameterDecl& integers(std::string key, std::optional<std::vector<std::int64_t>> def,
                          std::string doc);
  ParameterDecl& texts(std::string key, std::optional<std::vector<std::string>> def,
                       std::string doc);
  const ParameterDecl* find(const std::string& key) const;
};

/// All sections a scene may contain, in the order modules declared them.
class SceneSchema {
 public:
  /// Declares (or returns the already declared) section.
  SectionDecl& section(const std::string& name, const std::string& doc, bool repeated = false);
  const SectionDecl* find(const std::string& name) const;
  const std::deque<SectionDecl>& sections() const { return sections_; }
  /// The generated reference page (docs/scene-reference.md).
  std::string reference_markdown() const;

 private:
  std::deque<SectionDecl> sections_;
};

/// Edit distance, for "did you mean" suggestions.
std::size_t edit_distance(const std::string& a, const std::string& b);
/// The candidate closest to `word`, if close enough to be a plausible misspelling.
std::optional<std::string> closest_match(const std::string& word,
                                         const std::vector<std::string>& candidates);

}  // namespace grainwave
