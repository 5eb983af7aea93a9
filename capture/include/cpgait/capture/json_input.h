#pragma once
// JSON documents users hand us (task sets, calibrations, tag sets, boards): parsed with
// nlohmann-json, errors turned into InputError with the line of the offending byte.
#include <nlohmann/json.hpp>
#include <string>

namespace cpgait {

nlohmann::json parse_json_input(const std::string& text, const std::string& name);
[[noreturn]] void throw_json_field_error(const std::string& name, const std::string& field, const std::string& message);

// Reads `key` of object `j` as T; InputError naming `field_prefix.key` when absent or mistyped.
template <typename T>
T json_field(const nlohmann::json& j, const std::string& key, const std::string& name, const std::string& field_prefix) {
  const std::string field = field_prefix.empty() ? key : field_prefix + "." + key;
  if (!j.is_object() || !j.contains(key)) throw_json_field_error(name, field, "missing");
  try {
    return j.at(key).get<T>();
  } catch (const nlohmann::json::exception& e) {
    throw_json_field_error(name, field, std::string("wrong type: ") + e.what());
  }
  return T{};
}

// `key` of object `j` as T, or `fallback` when absent; InputError when present but mistyped.
template <typename T>
T json_field_or(const nlohmann::json& j, const std::string& key, const T& fallback, const std::string& name,
                const std::string& field_prefix) {
  return j.is_object() && j.contains(key) ? json_field<T>(j, key, name, field_prefix) : fallback;
}

}  // namespace cpgait
