#pragma once
// One description of an options struct gives its JSON reader (every error names the field's full
// path, e.g. "gait.residuals"), its writer (job.json) and its JSON Schema, so the three cannot drift.
// A struct opts in with `static const OptionFields<T>& fields();` (DescribedOptions).
#include <concepts>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/input_error.h"

namespace cpgait::services {

// Where a value being read came from: the document (for InputError) and the path to its object.
struct OptionPath {
  std::string source = "options";
  std::string prefix;  // "gait." inside the gait stage's object; empty at the top
  std::string field(const std::string& key) const { return prefix + key; }
  [[noreturn]] void fail(const std::string& key, const std::string& message) const {
    throw InputError(source, 0, key.empty() ? (prefix.empty() ? "options" : prefix.substr(0, prefix.size() - 1)) : field(key), message);
  }
};

// Bounds of a number; a missing bound is open.
struct NumberRange {
  std::optional<double> min, max;
  bool exclusive_min = false;
};

template <class T>
class OptionFields {
 public:
  struct Field {
    std::string key;
    nlohmann::json schema;  // type, range, unit, description (the default is filled in from T{})
    std::function<void(const nlohmann::json&, T&, const OptionPath&)> read;  // the key is present
    std::function<void(const T&, nlohmann::json&)> write;                     // sets obj[key] or leaves it out
  };

  explicit OptionFields(std::string description) : description_(std::move(description)) {}

  OptionFields& number(std::string key, double T::*m, std::string unit, std::string description, NumberRange r = {}) {
    nlohmann::json s = range_schema("number", r, unit, description);
    return add({key, s, [key, m, r, unit](const nlohmann::json& v, T& o, const OptionPath& p) { o.*m = read_number(v, key, r, unit, p); },
                [key, m](const T& o, nlohmann::json& j) { j[key] = o.*m; }});
  }
  // Left out of job.json when unset; the description says what unset means.
  OptionFields& optional_number(std::string key, std::optional<double> T::*m, std::string unit, std::string description,
                                NumberRange r = {}) {
    nlohmann::json s = range_schema("number", r, unit, description);
    return add({key, s, [key, m, r, unit](const nlohmann::json& v, T& o, const OptionPath& p) { o.*m = read_number(v, key, r, unit, p); },
                [key, m](const T& o, nlohmann::json& j) {
                  if (o.*m) j[key] = *(o.*m);
                }});
  }
  OptionFields& integer(std::string key, int T::*m, int min, int max, std::string description) {
    nlohmann::json s = {{"type", "integer"}, {"minimum", min}, {"maximum", max}, {"description", description}};
    return add({key, s,
                [key, m, min, max](const nlohmann::json& v, T& o, const OptionPath& p) {
                  if (!v.is_number_integer() && !(v.is_number_float() && v.get<double>() == static_cast<double>(static_cast<long>(v.get<double>()))))
                    p.fail(key, "expected a whole number");
                  const long x = v.get<long>();
                  if (x < min || x > max) p.fail(key, "expected " + std::to_string(min) + " to " + std::to_string(max));
                  o.*m = static_cast<int>(x);
                },
                [key, m](const T& o, nlohmann::json& j) { j[key] = o.*m; }});
  }
  OptionFields& boolean(std::string key, bool T::*m, std::string description) {
    return add({key, {{"type", "boolean"}, {"description", description}},
                [key, m](const nlohmann::json& v, T& o, const OptionPath& p) {
                  if (!v.is_boolean()) p.fail(key, "expected true or false");
                  o.*m = v.get<bool>();
                },
                [key, m](const T& o, nlohmann::json& j) { j[key] = o.*m; }});
  }
  OptionFields& integer_choice(std::string key, int T::*m, std::vector<int> values, std::string description) {
    std::string list;
    for (int v : values) list += (list.empty() ? "" : ", ") + std::to_string(v);
    return add({key, {{"type", "integer"}, {"enum", values}, {"description", description}},
                [key, m, values, list](const nlohmann::json& v, T& o, const OptionPath& p) {
                  if (!v.is_number_integer() || std::find(values.begin(), values.end(), v.get<long>()) == values.end())
                    p.fail(key, "expected one of " + list);
                  o.*m = v.get<int>();
                },
                [key, m](const T& o, nlohmann::json& j) { j[key] = o.*m; }});
  }
  OptionFields& choice(std::string key, std::string T::*m, std::vector<std::string> values, std::string description) {
    std::string list;
    for (const auto& v : values) list += (list.empty() ? "" : ", ") + nlohmann::json(v).dump();
    return add({key, {{"type", "string"}, {"enum", values}, {"description", description}},
                [key, m, values, list](const nlohmann::json& v, T& o, const OptionPath& p) {
                  if (!v.is_string() || std::find(values.begin(), values.end(), v.get<std::string>()) == values.end())
                    p.fail(key, "expected one of " + list);
                  o.*m = v.get<std::string>();
                },
                [key, m](const T& o, nlohmann::json& j) { j[key] = o.*m; }});
  }
  // A list of numbers, each within r, at most max_items of them, a multiple of `group` (a vector's
  // components one after another: 3 for x y z).
  OptionFields& number_list(std::string key, std::vector<double> T::*m, std::string unit, std::string description, NumberRange r,
                            std::size_t max_items, std::size_t group = 1) {
    nlohmann::json s = {{"type", "array"}, {"items", range_schema("number", r, unit, description)}, {"maxItems", max_items}, {"description", description}};
    s["items"].erase("description");
    if (!unit.empty()) s["x-unit"] = unit;
    if (group > 1) s["x-group"] = group;
    return add({key, s,
                [key, m, r, unit, max_items, group](const nlohmann::json& v, T& o, const OptionPath& p) {
                  if (!v.is_array()) p.fail(key, "expected an array of numbers");
                  if (v.size() > max_items) p.fail(key, "expected at most " + std::to_string(max_items) + " numbers");
                  if (v.size() % group != 0) p.fail(key, "expected a multiple of " + std::to_string(group) + " numbers, got " + std::to_string(v.size()));
                  std::vector<double> out;
                  for (std::size_t i = 0; i < v.size(); ++i) out.push_back(read_number(v[i], key + "[" + std::to_string(i) + "]", r, unit, p));
                  o.*m = out;
                },
                [key, m](const T& o, nlohmann::json& j) { j[key] = o.*m; }});
  }
  // A string, left out of job.json when empty.
  OptionFields& text(std::string key, std::string T::*m, std::string description) {
    return add({key, {{"type", "string"}, {"description", description}},
                [key, m](const nlohmann::json& v, T& o, const OptionPath& p) {
                  if (!v.is_string()) p.fail(key, "expected a string");
                  o.*m = v.get<std::string>();
                },
                [key, m](const T& o, nlohmann::json& j) {
                  if (!(o.*m).empty()) j[key] = o.*m;
                }});
  }
  OptionFields& add(Field f) {
    fields_.push_back(std::move(f));
    return *this;
  }

  // Reads the fields present; refuses a non-object and keys no field describes.
  void read(const nlohmann::json& j, T& out, const OptionPath& where) const {
    if (!j.is_object()) where.fail("", "expected a JSON object");
    for (const auto& [k, v] : j.items()) {
      const Field* f = find(k);
      if (!f) where.fail(k, "unknown option (expected one of: " + keys() + ")");
      f->read(v, out, where);
    }
  }
  nlohmann::json write(const T& o) const {
    nlohmann::json j = nlohmann::json::object();
    for (const Field& f : fields_) f.write(o, j);
    return j;
  }
  // The JSON Schema of the object, every default taken from `defaults`.
  nlohmann::json schema(const T& defaults_from = T{}) const {
    const nlohmann::json defaults = write(defaults_from);
    nlohmann::json props = nlohmann::json::object();
    for (const Field& f : fields_) {
      props[f.key] = f.schema;
      if (defaults.contains(f.key)) props[f.key]["default"] = defaults[f.key];
    }
    return {{"type", "object"}, {"description", description_}, {"additionalProperties", false}, {"properties", props}};
  }

 private:
  std::string description_;
  std::vector<Field> fields_;

  const Field* find(const std::string& key) const {
    for (const Field& f : fields_)
      if (f.key == key) return &f;
    return nullptr;
  }
  std::string keys() const {
    std::string s;
    for (const Field& f : fields_) s += (s.empty() ? "" : ", ") + f.key;
    return s;
  }
  static std::string range_text(const NumberRange& r, const std::string& unit) {
    auto num = [](double x) {
      std::string s = nlohmann::json(x).dump();
      return s.size() > 2 && s.substr(s.size() - 2) == ".0" ? s.substr(0, s.size() - 2) : s;
    };
    const std::string u = unit.empty() ? "" : " " + unit;
    if (r.min && r.max) return (r.exclusive_min ? "above " + num(*r.min) + " and up to " : num(*r.min) + " to ") + num(*r.max) + u;
    if (r.min) return (r.exclusive_min ? "above " : "at least ") + num(*r.min) + u;
    if (r.max) return "at most " + num(*r.max) + u;
    return "a number" + (unit.empty() ? "" : " in " + unit);
  }
  static nlohmann::json range_schema(const char* type, const NumberRange& r, const std::string& unit, const std::string& description) {
    nlohmann::json s = {{"type", type}, {"description", description}};
    if (!unit.empty()) s["x-unit"] = unit;
    if (r.min) s[r.exclusive_min ? "exclusiveMinimum" : "minimum"] = *r.min;
    if (r.max) s["maximum"] = *r.max;
    return s;
  }
  static double read_number(const nlohmann::json& v, const std::string& key, const NumberRange& r, const std::string& unit,
                            const OptionPath& p) {
    if (!v.is_number()) p.fail(key, "expected a number");
    const double x = v.get<double>();
    if ((r.min && (r.exclusive_min ? !(x > *r.min) : !(x >= *r.min))) || (r.max && !(x <= *r.max)))
      p.fail(key, "expected " + range_text(r, unit));
    return x;
  }
};

template <class T>
concept DescribedOptions = requires {
  { T::fields() } -> std::same_as<const OptionFields<T>&>;
};

}  // namespace cpgait::services
