#pragma once
// OpenSim's Model::scale with the ScaleTool's factors: each body's centre of mass, joint frames,
// markers, path points (moving points' functions too) and wrap objects (positions and dimensions, as
// each shape's extendScale does) by their own body's factors; custom joints' translation functions by
// the parent's factor along their axis (the identity q is left alone); inertial properties as Body::scaleInertialProperties does them (with
// preserve_mass_distribution the masses keep their shares); then every mass and inertia times
// subject mass / total, and the muscles' fibre and tendon slack lengths by their path-length ratio
// (scale_muscle_parameters).
#include <Eigen/Core>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

// factors: one per model body (ground's ignored); subject_mass_kg <= 0 keeps the scaled masses.
Model scale_model(const Model& generic, const std::vector<Eigen::Vector3d>& factors, bool preserve_mass_distribution,
                  double subject_mass_kg);

}  // namespace cpgait
