#pragma once
// Gait events from kinematics alone, for trials without force plates.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

// Heel strikes by Zeni et al. (2008): the foot's forward distance from the pelvis, along the
// direction of progression (where the pelvis faces: its x axis, made horizontal), peaks at heel
// strike. Works overground and on a treadmill. Returns
// the times (s) of those peaks, at least min_cycle_s apart, refined by a parabola through the peak
// sample. q: frames x coordinates (rad or m).
std::vector<double> heel_strikes_zeni(const Model& model, const std::vector<double>& time_s, const Eigen::MatrixXd& q,
                                      const std::string& foot_body, double min_cycle_s = 0.6);

}  // namespace cpgait
