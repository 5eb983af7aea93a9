#include "cpgait/dynamics/forward_dynamics.h"

namespace cpgait {

void forward_dynamics(const Model& model, const double* q, const double* qd, const double* tau,
                      const std::vector<Vector6d>& external, ForwardDynamicsWorkspace& ws, double* qdd) {
  const int n = model.num_coordinates();
  rnea_kinematics(model, q, qd, ws.dynamics);  // pose, S and dS/dt once, for CRBA and the bias
  kinematics_values(ws.dynamics, ws.kinematics, ws.S);
  crba(model, ws.kinematics, ws.S, ws.M, ws.composite);
  rnea_from_kinematics(model, qd, ws.zero.data(), external, ws.dynamics, ws.bias.data());  // C + G - J^T f
  ws.llt.compute(ws.M);
  Eigen::Map<Eigen::VectorXd>(qdd, n) = ws.llt.solve(Eigen::Map<const Eigen::VectorXd>(tau, n) - ws.bias);
}

double mechanical_energy(const Model& model, const double* q, const double* qd, ForwardDynamicsWorkspace& ws) {
  forward_kinematics(model, q, ws.kinematics);
  motion_subspace(model, q, ws.kinematics, ws.S);
  crba(model, ws.kinematics, ws.S, ws.M, ws.composite);
  const Eigen::Map<const Eigen::VectorXd> v(qd, model.num_coordinates());
  double potential = 0;
  for (std::size_t b = 1; b < model.bodies.size(); ++b) {
    const auto& X = ws.kinematics.body_in_ground[b];
    potential -= model.bodies[b].mass_kg * model.gravity_m_s2.dot(X.rotation * model.bodies[b].com_m + X.translation_m);
  }
  return 0.5 * v.dot(ws.M * v) + potential;
}

}  // namespace cpgait
