#pragma once
// A small JSON Schema checker for the keywords cpgait's options schema uses (type, enum, minimum,
// exclusiveMinimum, maximum, minItems, maxItems, items, properties, additionalProperties), so tests
// can check documents against the published schema without a schema library.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace cpgait::testing {

// Where `doc` breaks `schema`, one "path: reason" each; empty when it conforms.
inline std::vector<std::string> schema_violations(const nlohmann::json& schema, const nlohmann::json& doc, const std::string& path = "") {
  std::vector<std::string> out;
  const std::string at = path.empty() ? "(document)" : path;
  auto fail = [&](const std::string& why) { out.push_back(at + ": " + why); };
  if (schema.contains("type")) {
    const std::string t = schema["type"];
    const bool ok = (t == "object" && doc.is_object()) || (t == "array" && doc.is_array()) || (t == "string" && doc.is_string()) ||
                    (t == "boolean" && doc.is_boolean()) || (t == "number" && doc.is_number()) ||
                    (t == "integer" && (doc.is_number_integer() || (doc.is_number_float() && doc.get<double>() == static_cast<double>(static_cast<long>(doc.get<double>())))));
    if (!ok) {
      fail("expected " + t + ", got " + doc.dump());
      return out;
    }
  }
  if (schema.contains("enum") && std::find(schema["enum"].begin(), schema["enum"].end(), doc) == schema["enum"].end())
    fail(doc.dump() + " is not one of " + schema["enum"].dump());
  if (doc.is_number()) {
    const double x = doc.get<double>();
    if (schema.contains("minimum") && x < schema["minimum"].get<double>()) fail("below minimum");
    if (schema.contains("exclusiveMinimum") && x <= schema["exclusiveMinimum"].get<double>()) fail("not above exclusiveMinimum");
    if (schema.contains("maximum") && x > schema["maximum"].get<double>()) fail("above maximum");
  }
  if (doc.is_array()) {
    if (schema.contains("minItems") && doc.size() < schema["minItems"].get<std::size_t>()) fail("too few items");
    if (schema.contains("maxItems") && doc.size() > schema["maxItems"].get<std::size_t>()) fail("too many items");
    if (schema.contains("items"))
      for (std::size_t i = 0; i < doc.size(); ++i)
        for (auto& v : schema_violations(schema["items"], doc[i], path + "[" + std::to_string(i) + "]")) out.push_back(v);
  }
  if (doc.is_object() && schema.contains("properties")) {
    for (const auto& [k, v] : doc.items()) {
      const std::string sub = path.empty() ? k : path + "." + k;
      if (schema["properties"].contains(k)) {
        for (auto& e : schema_violations(schema["properties"][k], v, sub)) out.push_back(e);
      } else if (schema.value("additionalProperties", true) == false) {
        out.push_back(sub + ": not in the schema");
      }
    }
  }
  return out;
}

}  // namespace cpgait::testing
