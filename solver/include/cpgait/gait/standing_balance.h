#pragma once
// Standing balance once a walk has stopped (walk -> stand), in joint space so the muscle reflex turns
// it into excitations: the ankle strategy along the pelvis' heading and the hip strategy across it
// (Winter, "Human balance and posture control during standing and walking", Gait & Posture 1995).
// The centre of mass' lean over the middle of the feet, l = (c - m) / h (rad; c the centre of mass,
// m the mean of the feet's sphere centres, h the height of c over m), and its rate move
// - both ankles' targets by -(ankle_kp l_along + ankle_kv dl_along/dt), the way that turns the body
//   above them back over the feet;
// - both hips' ab/adduction targets by -(hip_kp l_across + hip_kv dl_across/dt), the way that carries
//   a level pelvis back across over the feet (the two legs and the pelvis a parallelogram: Winter's
//   loading and unloading of the legs).
// The ankle is each leg's joint nearest its foot that turns about an axis within 45 deg of the
// across direction, the hip's ab/adduction the hip's coordinate whose axis lies nearest the heading;
// a leg without one gets no feedback there (a planar model has no ab/adduction).
#include <Eigen/Core>
#include <vector>

#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/simbicon_balance.h"
#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

struct StandingBalanceGains {
  double ankle_kp = 3;  // ankle target change per forward lean (rad/rad; default 3)
  double ankle_kv = 1;  // the same per lean rate (rad/(rad/s) = s; default 1)
  double hip_kp = 3;    // hip ab/adduction target change per sideways lean (rad/rad; default 3)
  double hip_kv = 1;    // the same per lean rate (s; default 1)
};

// The joints the feedback moves, found once (see above); -1 where a leg has none.
struct StandingJoints {
  int ankle[2] = {-1, -1};
  int hip[2] = {-1, -1};
  std::vector<std::vector<int>> body_coordinates;  // per body: the coordinates that move it
};
StandingJoints standing_joints(const Model& model, const ContactSet& contacts, const SimbiconLegs& legs,
                               const KinematicsWorkspace<double>& kin, const MotionSubspace& S);

// Adds the feedback, scaled by share (0-1), to the reflex's joint errors e (rad). kin/S: the state's
// kinematics; u: its speeds.
void standing_balance_feedback(const Model& model, const ContactSet& contacts, const SimbiconLegs& legs, const StandingJoints& joints,
                               const StandingBalanceGains& gains, const KinematicsWorkspace<double>& kin, const MotionSubspace& S,
                               const Eigen::VectorXd& u, double share, Eigen::VectorXd& e);

}  // namespace cpgait
