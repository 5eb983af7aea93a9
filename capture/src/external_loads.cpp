#include "cpgait/capture/external_loads.h"

#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

namespace {

ExternalLoadsSpec external_loads_from(const xml::Document& d) {
  const std::string& path = d.name();
  const pugi::xml_node root = d.tool("ExternalLoads");
  ExternalLoadsSpec s;
  s.name = root.attribute("name").value();
  s.file = path;
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();  // caller may override
  s.datafile = d.text(root, "datafile");
  s.kinematics_file = d.text(root, "external_loads_model_kinematics_file");
  s.kinematics_cutoff_hz = d.number(root, "lowpass_cutoff_frequency_for_load_kinematics", -1);
  for (const auto& f : root.child("objects").children()) {
    if (f.type() != pugi::node_element) continue;
    if (std::string(f.name()) != "ExternalForce") d.fail(f, "unsupported load type (expected ExternalForce)");
    // 20302 files say <isDisabled>, current ones <appliesForce>.
    if (d.boolean(f, "isDisabled", false) || !d.boolean(f, "appliesForce", true)) continue;
    ExternalForceSpec e;
    e.name = f.attribute("name").value();
    e.line = d.line_of(f);
    e.applied_to_body = d.text(f, "applied_to_body");
    if (e.applied_to_body.empty()) d.fail(f, "ExternalForce without <applied_to_body>");
    e.force_expressed_in_body = d.text(f, "force_expressed_in_body", "ground");
    e.point_expressed_in_body = d.text(f, "point_expressed_in_body", "ground");
    e.force_identifier = d.text(f, "force_identifier");
    if (e.force_identifier.empty()) d.fail(f, "ExternalForce without <force_identifier>");
    e.point_identifier = d.text(f, "point_identifier");
    e.torque_identifier = d.text(f, "torque_identifier");
    s.forces.push_back(e);
  }
  return s;
}

}  // namespace

ExternalLoadsSpec read_external_loads(const std::string& path) {
  return external_loads_from(xml::Document::load_file(path));
}

ExternalLoadsSpec parse_external_loads(std::string content, const std::string& name) {
  return external_loads_from(xml::Document::load_string(std::move(content), name));
}

}  // namespace cpgait
