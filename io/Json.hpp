#pragma once
// A small ordered JSON value, enough to write summary.json and read it back in tests.
// Keys keep their insertion order so summaries read the same from run to run.
#include <cstdint>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace grainwave::io {

class Json {
 public:
  using Object = std::vector<std::pair<std::string, Json>>;
  using Array = std::vector<Json>;

  Json() = default;  // null
  Json(bool b) : v_(b) {}
  Json(double x) : v_(x) {}
  Json(int i) : v_(static_cast<std::int64_t>(i)) {}
  Json(long i) : v_(static_cast<std::int64_t>(i)) {}
  Json(long long i) : v_(static_cast<std::int64_t>(i)) {}
  Json(unsigned long i) : v_(static_cast<std::int64_t>(i)) {}
  Json(const char* s) : v_(std::string(s)) {}
  Json(std::string s) : v_(std::move(s)) {}
  Json(Array a) : v_(std::move(a)) {}
  static Json object() {
    Json j;
    j.v_ = Object{};
    return j;
  }

  bool is_object() const { return std::holds_alternative<Object>(v_); }
  /// Sets (or replaces) a key of an object, keeping the first insertion's position.
  Json& set(const std::string& key, Json value);
  /// The value of a key of an object, created as null if missing.
  Json& operator[](const std::string& key);
  const Json* find(const std::string& key) const;
  double number() const;
  const std::string& text() const { return std::get<std::string>(v_); }

  /// Pretty-printed with two-space indentation. Non-finite numbers are written as null
  /// (JSON has no NaN), so a reader sees "no value" rather than a wrong one.
  std::string dump(int indent = 0) const;
  /// Parses JSON text (throws std::runtime_error with the offset on malformed input).
  static Json parse(const std::string& text);

 private:
  std::variant<std::nullptr_t, bool, double, std::int64_t, std::string, Array, Object> v_{nullptr};
};

}  // namespace grainwave::io
