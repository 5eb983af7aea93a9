#pragma once
// Balance feedback for the reproduced gait after SIMBICON (Yin, Loken & van de Panne, 2007), in joint
// space so the muscle reflex turns it into excitations:
// - trunk: on each stance leg the hip's target moves by the hip rotation that, the femur held still,
//   turns the pelvis back to its reference orientation (femur held: dh = -J_hip^+ J_pelvis dp, from
//   the femur's angular Jacobians), so the stance hip's muscles right the pelvis;
// - foot placement: the swing leg's hip target moves its foot by
//     c_d (d - d_ref) + c_v (v - v_ref)   (horizontal, ground frame; own gains along and across),
//   d the pelvis' offset from the stance foot and v the pelvis' velocity, against the reference pose's
//   offset and the reference's mean velocity: too fast forward or sideways, the foot lands further that
//   way and brakes (Raibert's and SIMBICON's rule);
// - stance-foot hold: in single support the stance hip's target moves that foot, against the pelvis,
//   across the way by s_d (d - d_ref) + s_v (v - v_ref): the body drifting outward over the foot, the
//   hip abducts and pushes it back (a hip strategy in the frontal plane);
// - lateral ankle strategy: in single support the stance foot's joint that rolls it about the walking
//   direction (gait2392's subtalar) gets a target roll of a_d (d - d_ref) + a_v (v - v_ref) across the
//   way, pressing the foot's outer edge as the body moves out over it, which moves the centre of
//   pressure outward and pushes the body back (Hof 2007; Reimann et al. 2018);
// - swing hip in the world frame (SIMBICON's): the swing femur turned by a share of the pelvis'
//   orientation error, so the foot lands headed as the reference's whatever the pelvis' yaw.
// Legs are found by name: the joints from the root's body to a child named *_r / *_l (hips), and the
// contact spheres named *_r / *_l (feet); a model without them gets no balance feedback. The ankle
// strategy rolls the rotation below the hip whose axis lies closest to the walking direction, if
// within 60 deg of it (a planar model has none).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "cpgait/dynamics/contact.h"
#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

struct SimbiconGains {
  double trunk_kp = 0;     // share of the pelvis' orientation error added to the stance hip's (default 0: off)
  double trunk_kv = 0;     // the same for its angular velocity error (default 0)
  // c_d (m/m) and c_v (m/(m/s) = s) across and along the walking direction (the reference pelvis'
  // heading); default 0: off. Apart, because the pelvis' speed along the way swings within every
  // stride while across it drifts: on subject01 the same gains both ways fell sooner than none.
  double lateral_d = 0, lateral_v = 0;
  double sagittal_d = 0, sagittal_v = 0;
  // The stance-foot hold's s_d (m/m) and s_v (s), across the way (default 0: off).
  double stance_lateral_d = 0, stance_lateral_v = 0;
  // The lateral ankle strategy's a_d (rad/m) and a_v (rad s/m) (default 0: off).
  double ankle_d = 0, ankle_v = 0;
  // The swing hip's target in the world frame, SIMBICON's: this share (default 0: the pelvis' frame)
  // of the pelvis' orientation error (and its rate's) turns the swing femur too, so the foot lands
  // headed as the reference's, whatever the pelvis' yaw.
  double swing_world = 0;
  bool any() const {
    return trunk_kp != 0 || trunk_kv != 0 || lateral_d != 0 || lateral_v != 0 || sagittal_d != 0 || sagittal_v != 0 ||
           stance_lateral_d != 0 || stance_lateral_v != 0 || swing_world != 0 || ankle_d != 0 || ankle_v != 0;
  }
};

struct SimbiconLegs {
  std::vector<int> pelvis_rotations;      // the root's rotational coordinates
  std::vector<int> pelvis_translations;   // the root's translations
  int pelvis_body = -1;
  std::vector<int> hip[2];                // coordinates of each side's hip (0 right, 1 left)
  std::vector<int> spheres[2];            // each side's contact spheres
  std::vector<int> below_hip[2];          // each side's rotations below the hip (knee to toes)
  bool valid() const { return pelvis_body > 0 && !hip[0].empty() && !hip[1].empty() && !spheres[0].empty() && !spheres[1].empty(); }
  bool is_root(int c) const;              // one of the root's coordinates
};

// 0 for a name ending in _r, 1 for _l, -1 otherwise.
int side_of(const std::string& name);

SimbiconLegs simbicon_legs(const Model& model, const ContactSet& contacts);

// Whether the lateral ankle strategy has a joint to roll each foot on: at the model's default pose, a
// rotation below each hip within 60 deg of the pelvis' heading (gait2392's subtalar; a planar model has
// none, and its ankle gains would do nothing).
bool rolls_both_feet(const Model& model, const SimbiconLegs& legs);

// A body's heading: its x axis made horizontal and unit (ground x where it points straight up or down).
Eigen::Vector3d horizontal_heading(const KinematicsWorkspace<double>& kin, int body);

// Adds the balance feedback to the reflex's joint errors e (rad) and ed (rad/s), all coordinates.
// kin/S: the state's kinematics; u: its speeds; reference_kin: the reference pose's kinematics;
// e_pelvis/ed_pelvis: the pelvis rotations' errors (reference - state); v_ref: the reference's mean
// pelvis velocity (m/s, ground); contact_force_N: per sphere; stance: the load that makes a leg stance (N).
void simbicon_balance_feedback(const ContactSet& contacts, const SimbiconLegs& legs, const SimbiconGains& gains,
                               const KinematicsWorkspace<double>& kin, const MotionSubspace& S, const Eigen::VectorXd& u,
                               const KinematicsWorkspace<double>& reference_kin, const Eigen::VectorXd& e_pelvis,
                               const Eigen::VectorXd& ed_pelvis, const Eigen::Vector3d& v_ref,
                               const std::vector<Eigen::Vector3d>& contact_force_N, double stance_N, Eigen::VectorXd& e,
                               Eigen::VectorXd& ed);

}  // namespace cpgait
