#pragma once
// Actuators from an OpenSim ForceSet XML (CMC/SO/RRA actuator files, or a model's own ForceSet):
// CoordinateActuator, PointActuator, TorqueActuator and PathActuator. Muscles, and a PathActuator's path,
// are read with the model.
#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

namespace cpgait {

struct ActuatorSpec {
  enum class Kind { kCoordinate, kPoint, kTorque, kPath };  // kPath: the model's PathActuator of this name
  std::string name;
  Kind kind = Kind::kCoordinate;
  double optimal_force = 1.0;  // N or N m per unit control
  double min_control = -std::numeric_limits<double>::infinity();
  double max_control = std::numeric_limits<double>::infinity();
  std::string coordinate;                                   // kCoordinate
  std::string body;                                         // kPoint
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  bool point_is_global = false;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  bool force_is_global = false;
  std::string body_a, body_b;                               // kTorque: +torque on A, -torque on B
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
  bool torque_is_global = true;
  std::string file;
  int line = 0;
};

// Reads the actuators of a <ForceSet> (root, inside <OpenSimDocument>, or a model's). Other force
// types are listed in `skipped`.
std::vector<ActuatorSpec> read_actuators(const std::string& path, std::vector<std::string>* skipped = nullptr);
// The same from a document's text (an upload), errors naming `name`.
std::vector<ActuatorSpec> parse_actuators(const std::string& text, const std::string& name, std::vector<std::string>* skipped = nullptr);

}  // namespace cpgait
