#pragma once
// Actuators resolved against a model: the generalized force each produces per unit control.
#include <Eigen/Core>
#include <vector>

#include "cpgait/capture/actuator_set.h"
#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

class ResolvedActuators {
 public:
  // Throws InputError naming the actuator file and line when a body, coordinate or path actuator is
  // unknown.
  ResolvedActuators(const Model& model, std::vector<ActuatorSpec> specs);

  int size() const { return static_cast<int>(specs_.size()); }
  const ActuatorSpec& spec(int i) const { return specs_[i]; }
  // Column i: generalized forces (nq) of actuator i at control 1 (optimal_force included), at the
  // coordinates q with ws and S from forward_kinematics and motion_subspace there.
  void generalized_forces(const Model& model, const double* q, const KinematicsWorkspace<double>& ws, const MotionSubspace& S,
                          Eigen::Ref<Eigen::MatrixXd> columns) const;

 private:
  struct Resolved {
    int coordinate = -1, body = -1, body_a = -1, body_b = -1, path_actuator = -1;
  };
  std::vector<ActuatorSpec> specs_;
  std::vector<Resolved> resolved_;
};

}  // namespace cpgait
