#pragma once
// The "tasks" option of the stages that take IK task weights (ik, scale): a JSON object checked by the
// task reader, its errors named "<stage>.tasks.<field>".
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "cpgait/capture/ik_setup.h"
#include "options_fields.h"

namespace cpgait::services {

template <class T>
typename OptionFields<T>::Field ik_tasks_field(std::optional<nlohmann::json> T::*member, const std::string& description) {
  return {"tasks",
          {{"type", "object"}, {"description", description}},
          [member](const nlohmann::json& v, T& o, const OptionPath& p) {
            if (!v.is_object()) p.fail("tasks", "expected an object of IK tasks");
            try {
              parse_ik_tasks_json(v.dump(), p.source);
            } catch (const InputError& e) {
              p.fail(e.field().empty() ? "tasks" : "tasks." + e.field(), e.message());
            }
            o.*member = v;
          },
          [member](const T& o, nlohmann::json& j) {
            if (o.*member) j["tasks"] = *(o.*member);
          }};
}

}  // namespace cpgait::services
