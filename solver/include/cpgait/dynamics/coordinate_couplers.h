#pragma once
// OpenSim's CoordinateCouplerConstraint in the dynamics: the coupled (dependent) coordinate moves as
// scale * f(independent), so the model's motion has one freedom fewer per coupler. Equations of motion
// and static optimization's moment balance are projected onto the free coordinates, as Simbody's
// constraint forces do it (OpenSim's SO balances only the coordinates that are not constrained).
#include <Eigen/Core>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

// Every coordinate that no coupler drives, in model order.
std::vector<int> free_coordinates(const Model& model);

// Dependent speeds from the independent ones (qd_dep = scale f'(q_ind) qd_ind), and where qdd is
// given the dependent accelerations too (scale (f''(q_ind) qd_ind^2 + f'(q_ind) qdd_ind)).
void apply_coupler_rates(const Model& model, const double* q, double* qd, double* qdd = nullptr);

// G (nq x free): qd = G qd_free at pose q; the dependent rows hold scale f'(q_ind).
void coupler_velocity_map(const Model& model, const double* q, const std::vector<int>& free, Eigen::MatrixXd& G);

}  // namespace cpgait
