#include "cpgait/capture/actuator_set.h"

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

namespace {

std::vector<ActuatorSpec> actuators_of(const xml::Document& d, std::vector<std::string>* skipped) {
  const std::string& path = d.name();
  pugi::xml_node set = d.doc().document_element();
  if (std::string(set.name()) == "OpenSimDocument") set = set.first_child();
  if (std::string(set.name()) == "Model") set = set.child("ForceSet");
  if (!set || std::string(set.name()) != "ForceSet")
    throw InputError(path, 1, "ForceSet", "expected an OpenSim <ForceSet> of actuators");
  std::vector<ActuatorSpec> out;
  for (const auto& n : set.child("objects").children()) {
    if (n.type() != pugi::node_element) continue;
    const std::string type = n.name();
    ActuatorSpec a;
    a.name = n.attribute("name").value();
    a.file = path;
    a.line = d.line_of(n);
    if (type == "CoordinateActuator") {
      a.kind = ActuatorSpec::Kind::kCoordinate;
      a.coordinate = d.text(n, "coordinate");
      if (a.coordinate.empty()) d.fail(n, "CoordinateActuator without a <coordinate>");
    } else if (type == "PointActuator") {
      a.kind = ActuatorSpec::Kind::kPoint;
      a.body = d.text(n, "body");
      if (a.body.empty()) d.fail(n, "PointActuator without a <body>");
      a.point = d.vec3(n, "point", a.point);
      a.point_is_global = d.boolean(n, "point_is_global", false);
      a.direction = d.vec3(n, "direction", a.direction);
      a.force_is_global = d.boolean(n, "force_is_global", false);
      if (a.direction.norm() == 0) d.fail(n.child("direction"), "direction has zero length");
      a.direction.normalize();
    } else if (type == "TorqueActuator") {
      a.kind = ActuatorSpec::Kind::kTorque;
      a.body_a = d.text(n, "bodyA");
      a.body_b = d.text(n, "bodyB");
      if (a.body_a.empty()) d.fail(n, "TorqueActuator without a <bodyA>");
      a.axis = d.vec3(n, "axis", a.axis);
      a.torque_is_global = d.boolean(n, "torque_is_global", true);
      if (a.axis.norm() == 0) d.fail(n.child("axis"), "axis has zero length");
      a.axis.normalize();
    } else if (type == "PathActuator") {
      a.kind = ActuatorSpec::Kind::kPath;
    } else {
      if (skipped) skipped->push_back(path + ":" + std::to_string(a.line) + ": " + type + " '" + a.name + "' is not an actuator cpgait applies here");
      continue;
    }
    if (!d.boolean(n, "appliesForce", true) || d.boolean(n, "isDisabled", false)) continue;
    a.optimal_force = d.number(n, "optimal_force", 1.0);
    a.min_control = d.number(n, "min_control", a.min_control);
    a.max_control = d.number(n, "max_control", a.max_control);
    if (a.min_control > a.max_control) d.fail(n, "min_control is above max_control");
    out.push_back(a);
  }
  return out;
}

}  // namespace

std::vector<ActuatorSpec> read_actuators(const std::string& path, std::vector<std::string>* skipped) {
  return actuators_of(xml::Document::load_file(path), skipped);
}

std::vector<ActuatorSpec> parse_actuators(const std::string& text, const std::string& name, std::vector<std::string>* skipped) {
  return actuators_of(xml::Document::load_string(text, name), skipped);
}

}  // namespace cpgait
