#include "cpgait/dynamics/passive_generalized_forces.h"

#include "cpgait/model/expression.h"
#include "cpgait/muscles/muscle_path.h"

namespace cpgait {
namespace {

// SimTK::Function::Step: y0 below x0, y1 above x1, a quintic t^3 (10 - 15 t + 6 t^2) between.
double step(double y0, double y1, double x0, double x1, double x) {
  if (x <= x0) return y0;
  if (x >= x1) return y1;
  const double t = (x - x0) / (x1 - x0);
  return y0 + (y1 - y0) * t * t * t * (10 + t * (6 * t - 15));
}

}  // namespace

double coordinate_limit_force(const CoordinateLimitForce& f, double q, double qd) {
  const double k_up = step(0.0, f.upper_stiffness, f.upper_limit, f.upper_limit + f.transition, q);
  const double k_low = step(f.lower_stiffness, 0.0, f.lower_limit - f.transition, f.lower_limit, q);
  // Damping scales with how far each spring has switched on.
  const double on = (f.upper_stiffness > 0 ? k_up / f.upper_stiffness : 0.0) + (f.lower_stiffness > 0 ? k_low / f.lower_stiffness : 0.0);
  return -k_up * (q - f.upper_limit) + k_low * (f.lower_limit - q) - f.damping * on * qd;
}

double path_spring_tension(const PathSpring& s, double length_m, double lengthening_speed_m_s) {
  const double stretch = length_m > s.resting_length_m ? length_m - s.resting_length_m : 0.0;
  return s.stiffness_N_per_m * stretch * (1 + s.dissipation_s_per_m * lengthening_speed_m_s);
}

namespace {

void add_coordinate_forces(const Model& model, const double* q, const double* qd, double* tau) {
  for (const auto& f : model.coordinate_limit_forces) tau[f.coordinate] += coordinate_limit_force(f, q[f.coordinate], qd[f.coordinate]);
  for (const auto& f : model.spring_generalized_forces)
    tau[f.coordinate] += -f.stiffness * (q[f.coordinate] - f.rest_length) - f.viscosity * qd[f.coordinate];
  for (const auto& f : model.expression_based_coordinate_forces) {
    const double v[2] = {q[f.coordinate], qd[f.coordinate]};
    tau[f.coordinate] += f.expression->evaluate(v);
  }
}

}  // namespace

void add_passive_generalized_forces(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                                    const MotionSubspace& S, double* tau) {
  add_coordinate_forces(model, q, qd, tau);
  if (model.path_springs.empty()) return;  // no allocation on forward dynamics' every evaluation
  // A tension T shortening the path: tau = -T dL/dq (its power is -T dL/dt).
  Eigen::RowVectorXd dL_dq;
  for (const PathSpring& s : model.path_springs) {
    double length = 0, speed = 0;
    path_geometry(model, s, q, qd, ws, S, length, speed, dL_dq);
    const double tension = path_spring_tension(s, length, speed);
    for (int c = 0; c < model.num_coordinates(); ++c) tau[c] -= tension * dL_dq[c];
  }
}

void add_passive_generalized_forces(const Model& model, const double* q, const double* qd, double* tau) {
  if (model.path_springs.empty()) return add_coordinate_forces(model, q, qd, tau);
  KinematicsWorkspace<double> ws(model);
  forward_kinematics(model, q, ws);
  MotionSubspace S(model);
  motion_subspace(model, q, ws, S);
  add_passive_generalized_forces(model, q, qd, ws, S, tau);
}

}  // namespace cpgait
