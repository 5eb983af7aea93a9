#pragma once
// OpenSim's CoordinateCouplerConstraint in the dynamics: the coupled (dependent) coordinate moves as
// scale * f(independent), so the model's motion has one freedom fewer per coupler. Equations of motion
// and static optimization's moment balance are projected onto the free coordinates, as Simbody's
// constraint forces do it (OpenSim's SO balances only the coordinates that are not constrained).
#include <Eigen/Core>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

// Whether the model constrains any coordinate: a coupler, or a locked coordinate (held still at its
// default value, as OpenSim holds one: setting a locked coordinate's value is ignored).
bool has_coordinate_constraints(const Model& model);

// Every coordinate that no coupler drives and that is not locked, in model order.
std::vector<int> free_coordinates(const Model& model);

// Puts a state on its constraints: locked coordinates at their default values and at rest, coupled
// ones (and their speeds, and accelerations where qdd is given) on their functions.
void assemble_coordinate_constraints(const Model& model, double* q, double* qd, double* qdd = nullptr);

// Dependent speeds from the independent ones (qd_dep = scale f'(q_ind) qd_ind), and where qdd is
// given the dependent accelerations too (scale (f''(q_ind) qd_ind^2 + f'(q_ind) qdd_ind)); locked
// coordinates at rest.
void apply_coupler_rates(const Model& model, const double* q, double* qd, double* qdd = nullptr);

// G (nq x free): qd = G qd_free at pose q; the dependent rows hold scale f'(q_ind), locked rows zero.
void coupler_velocity_map(const Model& model, const double* q, const std::vector<int>& free, Eigen::MatrixXd& G);

}  // namespace cpgait
