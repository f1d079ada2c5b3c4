#pragma once
// A scene: a TOML file validated against the SceneSchema, with command-line overrides applied and
// every default filled in. Validation errors are InputErrors naming file, line and key.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/Error.hpp"
#include "core/Parameters.hpp"

namespace grainwave {

/// One section of a scene (or one entry of a repeated [[section]]), fully resolved.
class SceneSection {
 public:
  struct Entry {
    ParameterValue value;
    InputLocation where;      ///< where it was written, or the section header for defaults
    bool explicit_value = false;
  };

  SceneSection(std::string name, int index, InputLocation where)
      : name_(std::move(name)), index_(index), where_(std::move(where)) {}

  const std::string& name() const { return name_; }
  /// Entry number in a repeated section, -1 for a plain section.
  int index() const { return index_; }
  const InputLocation& where() const { return where_; }
  /// "run.t_end", or "particle.2.position" in a repeated section.
  std::string qualified(const std::string& key) const;

  bool flag(const std::string& key) const;
  std::int64_t integer(const std::string& key) const;
  double real(const std::string& key) const;
  const std::string& text(const std::string& key) const;
  const std::vector<double>& reals(const std::string& key) const;
  const std::vector<std::int64_t>& integers(const std::string& key) const;
  const std::vector<std::string>& texts(const std::string& key) const;
  const ParameterValue& value(const std::string& key) const;

  /// True if the scene (or an override) gave the key, false if the default was used.
  bool is_explicit(const std::string& key) const;
  InputLocation location(const std::string& key) const;
  /// Reports a semantic error about `key` (e.g. inconsistent with another key) at its location.
  [[noreturn]] void fail(const std::string& key, const std::string& message,
                         const std::string& hint = {}) const;

  std::map<std::string, Entry>& entries() { return entries_; }
  const std::map<std::string, Entry>& entries() const { return entries_; }

 private:
  const Entry& entry(const std::string& key) const;
  std::string name_;
  int index_;
  InputLocation where_;
  std::map<std::string, Entry> entries_;
};

class Scene {
 public:
  /// Reads, overrides (`section.key=value` strings) and validates. Throws InputError.
  static Scene load(const std::filesystem::path& file, const std::vector<std::string>& overrides,
                    const SceneSchema& schema);
  /// Same, from text already in memory (`file` names it in messages).
  static Scene parse(const std::string& text, const std::string& file,
                     const std::vector<std::string>& overrides, const SceneSchema& schema);

  const std::string& name() const { return name_; }
  const std::string& file() const { return file_; }
  const std::string& text() const { return text_; }
  const std::string& sha256() const { return sha256_; }
  const std::vector<std::string>& overrides() const { return overrides_; }

  bool has(const std::string& section) const { return sections_.count(section) != 0; }
  /// A plain section that is present (precondition: has(name)).
  const SceneSection& section(const std::string& name) const;
  /// The entries of a repeated section (empty if absent).
  const std::vector<SceneSection>& entries(const std::string& name) const;
  /// Sections present, in schema order.
  std::vector<std::string> present_sections() const { return order_; }

  /// Every present section with all parameters, defaults filled in, as TOML.
  std::string resolved_toml(const SceneSchema& schema) const;

 private:
  std::string name_, file_, text_, sha256_;
  std::vector<std::string> overrides_;
  std::map<std::string, std::vector<SceneSection>> sections_;
  std::vector<std::string> order_;
};

}  // namespace grainwave
