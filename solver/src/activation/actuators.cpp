#include "cpgait/activation/actuators.h"

#include "cpgait/capture/input_error.h"
#include "cpgait/muscles/muscle_path.h"

namespace cpgait {

ResolvedActuators::ResolvedActuators(const Model& model, std::vector<ActuatorSpec> specs) : specs_(std::move(specs)) {
  auto body = [&](const ActuatorSpec& a, const std::string& name, const char* field) {
    if (name.empty()) return -1;
    const int b = name == "ground" ? 0 : model.body_index(name);
    if (b < 0) throw InputError(a.file, a.line, field, "body '" + name + "' is not in the model");
    return b;
  };
  for (const auto& a : specs_) {
    Resolved r;
    if (a.kind == ActuatorSpec::Kind::kCoordinate) {
      r.coordinate = model.coordinate_index(a.coordinate);
      if (r.coordinate < 0) throw InputError(a.file, a.line, "coordinate", "coordinate '" + a.coordinate + "' is not in the model");
    }
    if (a.kind == ActuatorSpec::Kind::kPath) {
      for (std::size_t k = 0; k < model.path_actuators.size(); ++k)
        if (model.path_actuators[k].name == a.name) r.path_actuator = static_cast<int>(k);
      if (r.path_actuator < 0)
        throw InputError(a.file, a.line, "PathActuator", "'" + a.name + "' has no path in the model (cpgait reads a PathActuator's path from the model's ForceSet)");
    }
    r.body = body(a, a.body, "body");
    r.body_a = body(a, a.body_a, "bodyA");
    r.body_b = body(a, a.body_b, "bodyB");
    resolved_.push_back(r);
  }
}

void ResolvedActuators::generalized_forces(const Model& model, const double* q, const KinematicsWorkspace<double>& ws,
                                           const MotionSubspace& S, Eigen::Ref<Eigen::MatrixXd> columns) const {
  columns.setZero();
  Eigen::RowVectorXd dL_dq;
  // Adds J^T applied to a spatial force (moment about the ground origin, force) on `body`.
  auto apply = [&](int i, int body, const Eigen::Vector3d& moment, const Eigen::Vector3d& force) {
    for (int b = body; b > 0;) {
      const Joint& j = model.joints[model.bodies[b].joint];
      for (int c : j.coordinates)
        columns(c, i) += S.columns.col(c).head<3>().dot(moment) + S.columns.col(c).tail<3>().dot(force);
      b = j.parent_body;
    }
  };
  for (int i = 0; i < size(); ++i) {
    const ActuatorSpec& a = specs_[i];
    const Resolved& r = resolved_[i];
    switch (a.kind) {
      case ActuatorSpec::Kind::kCoordinate:
        columns(r.coordinate, i) = a.optimal_force;
        break;
      case ActuatorSpec::Kind::kPoint: {
        const auto& B = ws.body_in_ground[r.body];
        const Eigen::Vector3d p = a.point_is_global ? a.point : Eigen::Vector3d(B.rotation * a.point + B.translation_m);
        const Eigen::Vector3d f = a.optimal_force * (a.force_is_global ? a.direction : Eigen::Vector3d(B.rotation * a.direction));
        apply(i, r.body, p.cross(f), f);
        break;
      }
      case ActuatorSpec::Kind::kTorque: {
        const Eigen::Vector3d axis = a.torque_is_global ? a.axis : Eigen::Vector3d(ws.body_in_ground[r.body_a].rotation * a.axis);
        const Eigen::Vector3d t = a.optimal_force * axis;
        apply(i, r.body_a, t, Eigen::Vector3d::Zero());
        if (r.body_b > 0) apply(i, r.body_b, -t, Eigen::Vector3d::Zero());
        break;
      }
      case ActuatorSpec::Kind::kPath: {
        // A tension T along the path: tau = -T dL/dq.
        double length = 0, speed = 0;
        path_geometry(model, model.path_actuators[r.path_actuator], q, nullptr, ws, S, length, speed, dL_dq);
        columns.col(i) = -a.optimal_force * dL_dq.transpose();
        break;
      }
    }
  }
}

}  // namespace cpgait
