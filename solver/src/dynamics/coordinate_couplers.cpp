#include "cpgait/dynamics/coordinate_couplers.h"

namespace cpgait {

bool has_coordinate_constraints(const Model& model) {
  if (!model.couplers.empty()) return true;
  for (const auto& c : model.coordinates)
    if (c.locked) return true;
  return false;
}

std::vector<int> free_coordinates(const Model& model) {
  std::vector<bool> coupled(model.num_coordinates(), false);
  for (const auto& c : model.couplers) coupled[c.dependent] = true;
  std::vector<int> free;
  for (int i = 0; i < model.num_coordinates(); ++i)
    if (!coupled[i] && !model.coordinates[i].locked) free.push_back(i);
  return free;
}

void assemble_coordinate_constraints(const Model& model, double* q, double* qd, double* qdd) {
  for (int i = 0; i < model.num_coordinates(); ++i)
    if (model.coordinates[i].locked) q[i] = model.coordinates[i].default_value;
  apply_coordinate_couplers(model, q);
  apply_coupler_rates(model, q, qd, qdd);
}

void apply_coupler_rates(const Model& model, const double* q, double* qd, double* qdd) {
  for (int i = 0; i < model.num_coordinates(); ++i)
    if (model.coordinates[i].locked) {
      qd[i] = 0.0;
      if (qdd) qdd[i] = 0.0;
    }
  for (const auto& c : model.couplers) {
    const double x = q[c.independent], v = qd[c.independent];
    const double d1 = c.function.derivative(x);
    qd[c.dependent] = c.scale * d1 * v;
    if (qdd) qdd[c.dependent] = c.scale * (c.function.second_derivative(x) * v * v + d1 * qdd[c.independent]);
  }
}

void coupler_velocity_map(const Model& model, const double* q, const std::vector<int>& free, Eigen::MatrixXd& G) {
  const int nq = model.num_coordinates(), nf = static_cast<int>(free.size());
  G.setZero(nq, nf);
  std::vector<int> column(nq, -1);
  for (int j = 0; j < nf; ++j) {
    G(free[j], j) = 1.0;
    column[free[j]] = j;
  }
  for (const auto& c : model.couplers) G(c.dependent, column[c.independent]) = c.scale * c.function.derivative(q[c.independent]);
}

}  // namespace cpgait
