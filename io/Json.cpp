#include "io/Json.hpp"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>

namespace grainwave::io {

Json& Json::set(const std::string& key, Json value) {
  (*this)[key] = std::move(value);
  return *this;
}

Json& Json::operator[](const std::string& key) {
  if (std::holds_alternative<std::nullptr_t>(v_)) v_ = Object{};
  auto& obj = std::get<Object>(v_);
  for (auto& [k, v] : obj)
    if (k == key) return v;
  obj.emplace_back(key, Json{});
  return obj.back().second;
}

const Json* Json::find(const std::string& key) const {
  if (!is_object()) return nullptr;
  for (const auto& [k, v] : std::get<Object>(v_))
    if (k == key) return &v;
  return nullptr;
}

double Json::number() const {
  if (const auto* d = std::get_if<double>(&v_)) return *d;
  if (const auto* i = std::get_if<std::int64_t>(&v_)) return static_cast<double>(*i);
  if (std::holds_alternative<std::nullptr_t>(v_)) return NAN;
  throw std::runtime_error("JSON value is not a number");
}

namespace {
std::string escape(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (c < 0x20) out += fmt::format("\\u{:04x}", c);
        else out += static_cast<char>(c);
    }
  }
  return out + "\"";
}
}  // namespace

std::string Json::dump(int indent) const {
  const std::string pad(static_cast<std::size_t>(indent + 2), ' ');
  const std::string close_pad(static_cast<std::size_t>(indent), ' ');
  struct Visitor {
    int indent;
    const std::string& pad;
    const std::string& close_pad;
    std::string operator()(std::nullptr_t) const { return "null"; }
    std::string operator()(bool b) const { return b ? "true" : "false"; }
    std::string operator()(double d) const {
      if (!std::isfinite(d)) return "null";
      std::string s = fmt::format("{}", d);
      return s;
    }
    std::string operator()(std::int64_t i) const { return std::to_string(i); }
    std::string operator()(const std::string& s) const { return escape(s); }
    std::string operator()(const Array& a) const {
      if (a.empty()) return "[]";
      std::string out = "[";
      for (std::size_t i = 0; i < a.size(); ++i) out += (i ? ", " : "") + a[i].dump(indent + 2);
      return out + "]";
    }
    std::string operator()(const Object& o) const {
      if (o.empty()) return "{}";
      std::string out = "{\n";
      for (std::size_t i = 0; i < o.size(); ++i)
        out += pad + escape(o[i].first) + ": " + o[i].second.dump(indent + 2) +
               (i + 1 < o.size() ? ",\n" : "\n");
      return out + close_pad + "}";
    }
  };
  return std::visit(Visitor{indent, pad, close_pad}, v_);
}

namespace {
struct Parser {
  const std::string& s;
  std::size_t i = 0;

  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(fmt::format("malformed JSON at offset {}: {}", i, what));
  }
  void skip() {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\n' || s[i] == '\t' || s[i] == '\r')) ++i;
  }
  bool eat(char c) {
    skip();
    if (i < s.size() && s[i] == c) {
      ++i;
      return true;
    }
    return false;
  }
  std::string string_literal() {
    if (!eat('"')) fail("expected string");
    std::string out;
    while (i < s.size() && s[i] != '"') {
      if (s[i] == '\\') {
        if (++i >= s.size()) fail("bad escape");
        const char c = s[i++];
        if (c == 'n') out += '\n';
        else if (c == 't') out += '\t';
        else if (c == 'r') out += '\r';
        else if (c == 'u') {
          out += static_cast<char>(std::stoi(s.substr(i, 4), nullptr, 16));
          i += 4;
        } else out += c;
      } else {
        out += s[i++];
      }
    }
    if (i >= s.size()) fail("unterminated string");
    ++i;
    return out;
  }
  Json value() {
    skip();
    if (i >= s.size()) fail("unexpected end");
    const char c = s[i];
    if (c == '{') {
      ++i;
      Json obj = Json::object();
      if (eat('}')) return obj;
      do {
        std::string key = string_literal();
        if (!eat(':')) fail("expected ':'");
        obj.set(key, value());
      } while (eat(','));
      if (!eat('}')) fail("expected '}'");
      return obj;
    }
    if (c == '[') {
      ++i;
      Json::Array arr;
      if (eat(']')) return Json(arr);
      do arr.push_back(value());
      while (eat(','));
      if (!eat(']')) fail("expected ']'");
      return Json(arr);
    }
    if (c == '"') return Json(string_literal());
    if (s.compare(i, 4, "true") == 0) { i += 4; return Json(true); }
    if (s.compare(i, 5, "false") == 0) { i += 5; return Json(false); }
    if (s.compare(i, 4, "null") == 0) { i += 4; return Json(); }
    std::size_t used = 0;
    const std::string rest = s.substr(i, 64);
    const bool integral = rest.find_first_of(".eE") == std::string::npos ||
                          rest.find_first_of(".eE") > rest.find_first_of(",]}\n ");
    try {
      if (integral) {
        const long long v = std::stoll(rest, &used);
        i += used;
        return Json(v);
      }
      const double v = std::stod(rest, &used);
      i += used;
      return Json(v);
    } catch (const std::exception&) {
      fail("expected a value");
    }
  }
};
}  // namespace

Json Json::parse(const std::string& text) {
  Parser p{text};
  Json v = p.value();
  p.skip();
  if (p.i != text.size()) p.fail("trailing characters");
  return v;
}

}  // namespace grainwave::io
