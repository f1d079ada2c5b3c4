#include "core/Scene.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <toml.hpp>

#include "core/Sha256.hpp"

namespace grainwave {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// SceneSection

std::string SceneSection::qualified(const std::string& key) const {
  return index_ < 0 ? name_ + "." + key : fmt::format("{}.{}.{}", name_, index_, key);
}

const SceneSection::Entry& SceneSection::entry(const std::string& key) const {
  auto it = entries_.find(key);
  if (it == entries_.end())
    throw std::logic_error("scene parameter '" + qualified(key) + "' was never declared");
  return it->second;
}

const ParameterValue& SceneSection::value(const std::string& key) const { return entry(key).value; }

namespace {
template <class T>
const T& get_as(const SceneSection& s, const std::string& key) {
  const auto* v = std::get_if<T>(&s.value(key));
  if (!v) throw std::logic_error("scene parameter '" + s.qualified(key) + "' read with wrong type");
  return *v;
}
}  // namespace

bool SceneSection::flag(const std::string& key) const { return get_as<bool>(*this, key); }
std::int64_t SceneSection::integer(const std::string& key) const {
  return get_as<std::int64_t>(*this, key);
}
double SceneSection::real(const std::string& key) const { return get_as<double>(*this, key); }
const std::string& SceneSection::text(const std::string& key) const {
  return get_as<std::string>(*this, key);
}
const std::vector<double>& SceneSection::reals(const std::string& key) const {
  return get_as<std::vector<double>>(*this, key);
}
const std::vector<std::int64_t>& SceneSection::integers(const std::string& key) const {
  return get_as<std::vector<std::int64_t>>(*this, key);
}
const std::vector<std::string>& SceneSection::texts(const std::string& key) const {
  return get_as<std::vector<std::string>>(*this, key);
}
bool SceneSection::is_explicit(const std::string& key) const { return entry(key).explicit_value; }
InputLocation SceneSection::location(const std::string& key) const { return entry(key).where; }

void SceneSection::fail(const std::string& key, const std::string& message,
                        const std::string& hint) const {
  throw InputError(location(key), qualified(key), message, hint);
}

// ---------------------------------------------------------------------------------------------
// Parsing and validation

namespace {

struct Override {
  std::string text;     // as given: "run.t_end=2"
  std::string section;  // "run"
  int index = -1;       // entry of a repeated section
  std::string key;      // "t_end"
  toml::value value;
};

std::string describe_toml_type(const toml::value& v) {
  switch (v.type()) {
    case toml::value_t::boolean: return "bool";
    case toml::value_t::integer: return "integer";
    case toml::value_t::floating: return "real";
    case toml::value_t::string: return "string";
    case toml::value_t::array: return "array";
    case toml::value_t::table: return "table";
    default: return "date/time";
  }
}

std::string first_line(const std::string& s) {
  // toml11 messages are multi-line with a source excerpt; keep the gist on one line.
  std::string line = s.substr(0, s.find('\n'));
  const std::string tag = "[error] ";
  if (line.rfind(tag, 0) == 0) line = line.substr(tag.size());
  return line;
}

Override parse_override(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError({"command line", 0}, text, "--set expects section.key=value");
  Override o;
  o.text = text;
  const std::string path = text.substr(0, eq);
  const std::string raw = text.substr(eq + 1);
  std::vector<std::string> parts;
  std::stringstream ss(path);
  for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
  if (parts.size() == 2) {
    o.section = parts[0];
    o.key = parts[1];
  } else if (parts.size() == 3 && !parts[1].empty() &&
             parts[1].find_first_not_of("0123456789") == std::string::npos) {
    o.section = parts[0];
    o.index = std::stoi(parts[1]);
    o.key = parts[2];
  } else {
    throw InputError({"command line", 0}, path,
                     "--set expects section.key=value (or section.N.key=value for [[section]])");
  }
  // The value is TOML ("2.5", "[0, 1, 0]", "true", "\"fcc\""); a bare word is taken as a string.
  try {
    std::istringstream in("v = " + raw);
    o.value = toml::find(toml::parse(in, "--set " + text), "v");
  } catch (const std::exception&) {
    o.value = toml::value(raw);
  }
  return o;
}

void apply_override(toml::value& root, const Override& o) {
  auto& table = root.as_table();
  if (o.index < 0) {
    if (!table.count(o.section)) table[o.section] = toml::table{};
    if (!table[o.section].is_table())
      throw InputError({"command line", 0}, o.section,
                       "--set " + o.text + ": section is a list; use " + o.section + ".N." + o.key);
    table[o.section].as_table()[o.key] = o.value;
  } else {
    if (!table.count(o.section) || !table[o.section].is_array() ||
        static_cast<std::size_t>(o.index) >= table[o.section].as_array().size())
      throw InputError({"command line", 0}, o.section,
                       fmt::format("--set {}: the scene has no entry {} of [[{}]]", o.text,
                                   o.index, o.section));
    table[o.section].as_array()[static_cast<std::size_t>(o.index)].as_table()[o.key] = o.value;
  }
}

struct Validator {
  const SceneSchema& schema;
  const std::string& file;
  const std::vector<Override>& overrides;

  InputLocation where(const toml::value& v, const std::string& section, int index,
                      const std::string& key) const {
    for (const auto& o : overrides)
      if (o.section == section && o.key == key && o.index == index)
        return {"--set " + o.text, 0};
    const auto line = v.location().line();
    return {file, v.location().file_name() == file ? static_cast<int>(line) : 0};
  }

  static std::string qualified(const std::string& section, int index, const std::string& key) {
    return index < 0 ? section + "." + key : fmt::format("{}.{}.{}", section, index, key);
  }

  void check_number(double x, const ParameterDecl& d, const InputLocation& loc,
                    const std::string& qkey) const {
    if (!std::isfinite(x) && !(std::isinf(x) && ((x > 0 && !d.upper) || (x < 0 && !d.lower))))
      throw InputError(loc, qkey, fmt::format("value {} is not a finite number", x));
    const bool low_bad = d.lower && (d.lower_open ? x <= *d.lower : x < *d.lower);
    const bool high_bad = d.upper && (d.upper_open ? x >= *d.upper : x > *d.upper);
    if (low_bad || high_bad)
      throw InputError(loc, qkey, fmt::format("value {} is out of range {}", x, d.range_text()));
  }

  void check_choice(const std::string& s, const ParameterDecl& d, const InputLocation& loc,
                    const std::string& qkey) const {
    if (d.choices.empty()) return;
    for (const auto& c : d.choices)
      if (c == s) return;
    const auto guess = closest_match(s, d.choices);
    throw InputError(loc, qkey, fmt::format("'{}' is not {}", s, d.range_text()),
                     guess ? "did you mean '" + *guess + "'?" : std::string{});
  }

  [[noreturn]] void wrong_type(const toml::value& v, const ParameterDecl& d,
                               const InputLocation& loc, const std::string& qkey) const {
    throw InputError(loc, qkey,
                     fmt::format("expected {}, got {}", type_name(d.type), describe_toml_type(v)));
  }

  ParameterValue convert(const toml::value& v, const ParameterDecl& d, const InputLocation& loc,
                         const std::string& qkey) const {
    auto as_real = [&](const toml::value& x) -> double {
      if (x.is_floating()) return x.as_floating();
      if (x.is_integer()) return static_cast<double>(x.as_integer());
      wrong_type(x, d, loc, qkey);
    };
    auto elements = [&]() -> const toml::array& {
      if (!v.is_array()) wrong_type(v, d, loc, qkey);
      const auto& a = v.as_array();
      if (a.empty()) throw InputError(loc, qkey, "array must not be empty");
      if (d.length > 0 && static_cast<int>(a.size()) != d.length)
        throw InputError(loc, qkey,
                         fmt::format("expected {} values, got {}", d.length, a.size()));
      return a;
    };
    switch (d.type) {
      case ParameterType::kBool:
        if (!v.is_boolean()) wrong_type(v, d, loc, qkey);
        return v.as_boolean();
      case ParameterType::kInt: {
        if (!v.is_integer()) wrong_type(v, d, loc, qkey);
        const std::int64_t i = v.as_integer();
        check_number(static_cast<double>(i), d, loc, qkey);
        return i;
      }
      case ParameterType::kReal: {
        const double x = as_real(v);
        check_number(x, d, loc, qkey);
        return x;
      }
      case ParameterType::kString: {
        if (!v.is_string()) wrong_type(v, d, loc, qkey);
        const std::string s = v.as_string().str;
        check_choice(s, d, loc, qkey);
        return s;
      }
      case ParameterType::kRealArray: {
        std::vector<double> out;
        for (const auto& x : elements()) {
          out.push_back(as_real(x));
          check_number(out.back(), d, loc, qkey);
        }
        return out;
      }
      case ParameterType::kIntArray: {
        std::vector<std::int64_t> out;
        for (const auto& x : elements()) {
          if (!x.is_integer()) wrong_type(x, d, loc, qkey);
          out.push_back(x.as_integer());
          check_number(static_cast<double>(out.back()), d, loc, qkey);
        }
        return out;
      }
      case ParameterType::kStringArray: {
        std::vector<std::string> out;
        for (const auto& x : elements()) {
          if (!x.is_string()) wrong_type(x, d, loc, qkey);
          out.push_back(x.as_string().str);
          check_choice(out.back(), d, loc, qkey);
        }
        return out;
      }
    }
    throw std::logic_error("unhandled parameter type");
  }

  /// A key of another section that `key` is probably a misspelling of, qualified.
  std::optional<std::string> match_in_other_sections(const std::string& key,
                                                     const std::string& section) const {
    for (const auto& s : schema.sections()) {
      if (s.name == section) continue;
      std::vector<std::string> keys;
      for (const auto& p : s.parameters) keys.push_back(p.key);
      if (auto guess = closest_match(key, keys)) return s.name + "." + *guess;
    }
    return std::nullopt;
  }

  SceneSection section(const toml::value& table, const SectionDecl& decl, int index) const {
    InputLocation header{file, table.location().file_name() == file
                                   ? static_cast<int>(table.location().line())
                                   : 0};
    SceneSection out(decl.name, index, header);
    std::vector<std::string> known;
    for (const auto& p : decl.parameters) known.push_back(p.key);
    for (const auto& [key, v] : table.as_table()) {
      const ParameterDecl* d = decl.find(key);
      const InputLocation loc = where(v, decl.name, index, key);
      if (!d) {
        std::string hint;
        if (auto guess = closest_match(key, known)) {
          hint = "did you mean '" + decl.name + "." + *guess + "'?";
        } else if (auto elsewhere = match_in_other_sections(key, decl.name)) {
          hint = "did you mean '" + *elsewhere + "'?";
        } else {
          hint = "known keys: ";
          for (std::size_t i = 0; i < known.size(); ++i) hint += (i ? ", " : "") + known[i];
        }
        throw InputError(loc, qualified(decl.name, index, key),
                         "unknown key in [" + decl.name + "]", hint);
      }
      out.entries()[key] = {convert(v, *d, loc, qualified(decl.name, index, key)), loc, true};
    }
    for (const auto& p : decl.parameters) {
      if (out.entries().count(p.key)) continue;
      if (p.required())
        throw InputError(header, qualified(decl.name, index, p.key),
                         "required key is missing from [" + decl.name + "]",
                         p.key + ": " + p.doc);
      out.entries()[p.key] = {*p.default_value, header, false};
    }
    return out;
  }
};

}  // namespace

Scene Scene::load(const fs::path& file, const std::vector<std::string>& overrides,
                  const SceneSchema& schema) {
  std::ifstream in(file, std::ios::binary);
  if (!in)
    throw InputError({file.string(), 0}, "",
                     std::string("cannot read scene file: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError({file.string(), 0}, "", "cannot read scene file");
  return parse(text.str(), file.string(), overrides, schema);
}

Scene Scene::parse(const std::string& text, const std::string& file,
                   const std::vector<std::string>& override_texts, const SceneSchema& schema) {
  toml::value root;
  try {
    std::istringstream in(text);
    root = toml::parse(in, file);
  } catch (const toml::syntax_error& e) {
    throw InputError({file, static_cast<int>(e.location().line())}, "",
                     "malformed TOML: " + first_line(e.what()));
  } catch (const std::exception& e) {
    throw InputError({file, 0}, "", std::string("malformed TOML: ") + first_line(e.what()));
  }

  std::vector<Override> overrides;
  for (const auto& o : override_texts) overrides.push_back(parse_override(o));
  for (const auto& o : overrides) apply_override(root, o);

  Scene scene;
  scene.file_ = file;
  scene.text_ = text;
  scene.sha256_ = sha256_hex(text);
  scene.overrides_ = override_texts;

  Validator validator{schema, file, overrides};
  std::vector<std::string> section_names;
  for (const auto& s : schema.sections()) section_names.push_back(s.name);

  for (const auto& [name, v] : root.as_table()) {
    const SectionDecl* decl = schema.find(name);
    const InputLocation loc = validator.where(v, name, -1, "");
    if (!decl) {
      auto guess = closest_match(name, section_names);
      throw InputError(loc, name, v.is_table() ? "unknown section" : "unknown key",
                       guess ? "did you mean '[" + *guess + "]'?"
                             : "keys belong in a [section]; see docs/scene-reference.md");
    }
    if (decl->repeated) {
      if (!v.is_array() || v.as_array().empty() || !v.as_array().front().is_table())
        throw InputError(loc, name, "expected a list of tables",
                         "write each entry as [[" + name + "]]");
      int index = 0;
      for (const auto& entry : v.as_array())
        scene.sections_[name].push_back(validator.section(entry, *decl, index++));
    } else {
      if (!v.is_table())
        throw InputError(loc, name, "expected a table", "write it as [" + name + "]");
      scene.sections_[name].push_back(validator.section(v, *decl, -1));
    }
  }
  for (const auto& s : schema.sections())
    if (scene.sections_.count(s.name)) scene.order_.push_back(s.name);

  const std::string stem = fs::path(file).stem().string();
  scene.name_ = stem.empty() ? "scene" : stem;
  if (scene.has("scene") && scene.section("scene").is_explicit("name"))
    scene.name_ = scene.section("scene").text("name");
  return scene;
}

const SceneSection& Scene::section(const std::string& name) const {
  auto it = sections_.find(name);
  if (it == sections_.end() || it->second.empty() || it->second.front().index() >= 0)
    throw std::logic_error("scene has no plain section [" + name + "]");
  return it->second.front();
}

const std::vector<SceneSection>& Scene::entries(const std::string& name) const {
  static const std::vector<SceneSection> none;
  auto it = sections_.find(name);
  return it == sections_.end() ? none : it->second;
}

std::string Scene::resolved_toml(const SceneSchema& schema) const {
  std::ostringstream out;
  for (const auto& name : order_) {
    const SectionDecl* decl = schema.find(name);
    for (const auto& s : sections_.at(name)) {
      out << (decl->repeated ? "[[" + name + "]]" : "[" + name + "]") << "\n";
      for (const auto& p : decl->parameters) {
        const auto& e = s.entries().at(p.key);
        out << fmt::format("{:<24} = {:<28} # {}{}\n", p.key, to_toml(e.value),
                           e.explicit_value ? "" : "(default) ", p.doc);
      }
      out << "\n";
    }
  }
  return out.str();
}

}  // namespace grainwave
