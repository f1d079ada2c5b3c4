#pragma once
// A small name -> number bag that configures a contact law, so laws stay independent of the
// scene format: the scene layer copies a TOML table into it. Every key a law does not read is
// reported by check_all_used(), so typos are errors rather than silently ignored.
#include <map>
#include <set>
#include <string>
#include <string_view>

namespace grainwave::particles::dem {

class LawParameters {
 public:
  LawParameters() = default;
  LawParameters(std::initializer_list<std::pair<const std::string, double>> values)
      : values_(values) {}

  void set(const std::string& key, double value) { values_[key] = value; }
  bool contains(const std::string& key) const { return values_.count(key) != 0; }
  /// Value of a required key; throws grainwave::Error naming the law and the key when absent.
  double get(const std::string& key, std::string_view law) const;
  double get_or(const std::string& key, double fallback) const;
  /// Throws when a key was never read by get/get_or (a misspelt or foreign parameter).
  void check_all_used(std::string_view law) const;

 private:
  std::map<std::string, double> values_;
  mutable std::set<std::string> used_;
};

}  // namespace grainwave::particles::dem
