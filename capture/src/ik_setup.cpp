#include "cpgait/capture/ik_setup.h"

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {
namespace {

IkCoordinateTask::ValueType value_type_from(const std::string& s, const std::function<void(const std::string&)>& fail) {
  if (s.empty() || s == "default_value") return IkCoordinateTask::ValueType::kDefaultValue;
  if (s == "manual_value") return IkCoordinateTask::ValueType::kManualValue;
  if (s == "from_file") return IkCoordinateTask::ValueType::kFromFile;
  fail("expected default_value, manual_value or from_file, found '" + s + "'");
  return IkCoordinateTask::ValueType::kDefaultValue;
}

IkTaskSet parse_task_set(const xml::Document& d, const pugi::xml_node& set, const std::string& base_dir);

IkTaskSet task_set_from(const xml::Document& d, const pugi::xml_node& set, const std::string& base_dir) {
  // <IKTaskSet file="tasks.xml"/> refers to another file, relative to the referring one.
  if (const auto file = set.attribute("file"); file && *file.value()) {
    return read_ik_tasks((std::filesystem::path(base_dir) / file.value()).string());
  }
  return parse_task_set(d, set, base_dir);
}

IkTaskSet parse_task_set(const xml::Document& d, const pugi::xml_node& set, const std::string&) {
  IkTaskSet tasks;
  const auto objects = set.child("objects");
  for (const auto& node : objects.children()) {
    const std::string kind = node.name();
    const std::string name = node.attribute("name").value();
    if (kind == "IKMarkerTask") {
      if (name.empty()) d.fail(node, "IKMarkerTask without a name");
      tasks.markers.push_back({name, d.number(node, "weight", 1.0), d.boolean(node, "apply", true)});
    } else if (kind == "IKCoordinateTask") {
      if (name.empty()) d.fail(node, "IKCoordinateTask without a name");
      IkCoordinateTask t;
      t.name = name;
      t.weight = d.number(node, "weight", 1.0);
      t.apply = d.boolean(node, "apply", true);
      t.value_type = value_type_from(d.text(node, "value_type"), [&](const std::string& m) {
        d.fail(node.child("value_type"), m);
      });
      t.value = d.number(node, "value", 0.0);
      tasks.coordinates.push_back(t);
    } else if (node.type() == pugi::node_element) {
      d.fail(node, "unknown task type (expected IKMarkerTask or IKCoordinateTask)");
    }
  }
  return tasks;
}

}  // namespace

IkSetup read_ik_setup(const std::string& path) {
  const auto d = xml::Document::load_file(path);
  const pugi::xml_node tool = d.tool("InverseKinematicsTool");
  IkSetup s;
  s.name = tool.attribute("name").value();
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  s.model_file = d.text(tool, "model_file");
  s.marker_file = d.text(tool, "marker_file");
  s.coordinate_file = d.text(tool, "coordinate_file");
  // An empty results_directory means the setup's folder, as a missing one does.
  s.results_directory = d.text(tool, "results_directory", std::string(1, '.'));
  if (s.results_directory.empty()) s.results_directory.push_back('.');
  s.output_motion_file = d.text(tool, "output_motion_file");
  s.report_errors = d.boolean(tool, "report_errors", true);
  s.accuracy = d.number(tool, "accuracy", 1e-5);
  s.constraint_weight = d.number(tool, "constraint_weight", 20);
  s.time_range_s = d.time_range(tool);
  if (s.marker_file.empty()) throw InputError(path, d.line_of(tool), "marker_file", "the IK setup names no marker file");
  if (const auto set = tool.child("IKTaskSet")) s.tasks = task_set_from(d, set, s.setup_dir);
  return s;
}

IkTaskSet read_ik_tasks(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".json") return parse_ik_tasks_json(text::read_file(path), path);
  const auto d = xml::Document::load_file(path);
  auto root = d.doc().document_element();
  if (std::string(root.name()) == "OpenSimDocument") root = root.first_child();
  if (std::string(root.name()) == "InverseKinematicsTool") root = root.child("IKTaskSet");
  if (!root || std::string(root.name()) != "IKTaskSet")
    throw InputError(path, d.line_of(root), "IKTaskSet", "expected an <IKTaskSet> document");
  return parse_task_set(d, root, std::filesystem::absolute(path).parent_path().string());
}

IkTaskSet parse_ik_tasks_json(const std::string& content, const std::string& name) {
  const nlohmann::json j = parse_json_input(content, name);
  if (!j.is_object()) throw InputError(name, 0, "", "expected a JSON object with \"markers\" and \"coordinates\"");
  IkTaskSet tasks;
  // A task is a weight, or an object of its fields: reads the weight and `apply` into t and returns
  // the task's field name for the rest ("" for a bare weight). Each list is an object by name.
  auto weight_and_apply = [&](auto& t, const std::string& list, const std::string& task, const nlohmann::json& v) {
    if (v.is_number()) {
      t.weight = v.get<double>();
      return std::string();
    }
    const std::string field = list + "." + task;
    if (!v.is_object()) throw InputError(name, 0, field, "expected a weight or an object {\"weight\", \"apply\", ...}");
    t.weight = json_field_or(v, "weight", 1.0, name, field);
    t.apply = json_field_or(v, "apply", true, name, field);
    return field;
  };
  for (const char* list : {"markers", "coordinates"})
    if (j.contains(list) && !j[list].is_object()) throw InputError(name, 0, list, "expected an object of tasks by name");
  if (j.contains("markers"))
    for (const auto& [marker, v] : j["markers"].items()) {
      IkMarkerTask t{marker};
      weight_and_apply(t, "markers", marker, v);
      tasks.markers.push_back(t);
    }
  if (j.contains("coordinates"))
    for (const auto& [coord, v] : j["coordinates"].items()) {
      IkCoordinateTask t;
      t.name = coord;
      const std::string field = weight_and_apply(t, "coordinates", coord, v);
      if (!field.empty()) {
        t.value = json_field_or(v, "value", 0.0, name, field);
        t.value_type = value_type_from(json_field_or(v, "value_type", std::string("default_value"), name, field),
                                       [&](const std::string& m) { throw InputError(name, 0, field + ".value_type", m); });
      }
      tasks.coordinates.push_back(t);
    }
  return tasks;
}

std::string ik_tasks_json(const IkTaskSet& tasks) {
  nlohmann::json j = {{"markers", nlohmann::json::object()}, {"coordinates", nlohmann::json::object()}};
  for (const auto& t : tasks.markers) j["markers"][t.name] = {{"weight", t.weight}, {"apply", t.apply}};
  for (const auto& t : tasks.coordinates) {
    const char* type = t.value_type == IkCoordinateTask::ValueType::kManualValue ? "manual_value"
                       : t.value_type == IkCoordinateTask::ValueType::kFromFile  ? "from_file"
                                                                                  : "default_value";
    j["coordinates"][t.name] = {{"weight", t.weight}, {"apply", t.apply}, {"value_type", type}, {"value", t.value}};
  }
  return j.dump();
}

IkTaskSet read_ik_task_set(const xml::Document& d, const pugi::xml_node& set, const std::string& base_dir) {
  return task_set_from(d, set, base_dir);
}

}  // namespace cpgait
