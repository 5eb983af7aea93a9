#pragma once
// The pose a walk that stops comes to stand in (walk -> stand): a starting pose (the model's default)
// with the pelvis' place and the legs' joints changed, the pelvis' orientation kept, so that each foot
// lies flat on the ground (its rearmost and foremost contact spheres' lowest points at the ground's
// height, its heading kept) and the centre of mass stands over the middle of the feet; the feet may
// move. Gauss-Newton on those residuals (m) with a central-difference Jacobian, each step the
// smallest change from the starting pose that meets them linearised.
#include <Eigen/Core>

#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/simbicon_balance.h"

namespace cpgait {

struct StandingPoseSummary {
  double residual_m = 0;  // the residuals' largest magnitude at the end
  int iterations = 0;
};

// q: the starting pose (all coordinates); ground_height_m: where the feet rest. Only the pelvis'
// translations and the joints between the pelvis and each foot's rearmost-sphere body move; without
// legs (legs.valid() false) q comes back unchanged.
Eigen::VectorXd standing_pose(const Model& model, const ContactSet& contacts, const SimbiconLegs& legs, const Eigen::VectorXd& q,
                              double ground_height_m, StandingPoseSummary* summary = nullptr);

}  // namespace cpgait
