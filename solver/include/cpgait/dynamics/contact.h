#pragma once
// Foot-ground contact for simulations without force plates: smooth sphere/half-space contact after
// Hunt & Crossley (1975) with the smoothing of Serrancoli et al. (2019), OpenSim's
// SmoothSphereHalfSpaceForce. Spheres are fixed on bodies; the ground is the plane y = height.
//   penetration d = r - (y_centre - height), smoothed positive part d+ = (d + sqrt(d^2 + eps^2)) / 2
//   normal      Fn = k d+^1.5 (1 + 1.5 c d'), d' = -v_y (compressing > 0), clamped at >= 0
//   friction    Ft = -mu(|vt|) Fn vt/|vt|, mu rising smoothly (Stribeck) from 0 through mu_s to mu_d
// Parameters come from a JSON side file (schema below) so any model can get feet.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/model.h"

namespace cpgait {

struct ContactSphere {
  std::string name;
  int body = 0;
  Eigen::Vector3d location_m = Eigen::Vector3d::Zero();  // centre, in the body frame
  double radius_m = 0.035;
  double stiffness = 1e6;             // k, N/m^1.5
  double dissipation = 2.0;           // c, s/m (Hunt-Crossley)
  double static_friction = 0.8;
  double dynamic_friction = 0.8;
  double viscous_friction = 0.5;      // s/m
  double transition_velocity = 0.2;   // m/s: the Stribeck peak
};

struct ContactSet {
  double ground_height_m = 0.0;
  // The ground's own velocity (m/s, ground frame): a treadmill belt. Friction acts on the velocity
  // relative to it.
  Eigen::Vector3d ground_velocity_m_s = Eigen::Vector3d::Zero();
  double smoothing_m = 1e-5;  // eps: the penetration below which the force fades out smoothly
  // A step in the ground: past its edge (ground x >= step_x_m, the edge carried by the belt: at time t
  // it lies at step_x_m + v_belt,x t) the ground is step_height_m higher (m; negative: a step down),
  // the edge smoothed over step_edge_m (m). Default 0: level.
  double step_height_m = 0, step_x_m = 0, step_edge_m = 0.005;
  std::vector<ContactSphere> spheres;
};

// A sphere's centre (m, ground frame) in the pose kin holds.
Eigen::Vector3d sphere_centre_m(const KinematicsWorkspace<double>& kin, const ContactSphere& s);

// The ground's height (m, ground y) at ground x (m) and time t (s).
double ground_height_at(const ContactSet& set, double x_m, double t_s);

// The force (N, ground frame) the ground applies at the sphere's lowest point, from the sphere
// centre's position and the velocity in ground of the sphere's material point there (the contact
// point: the centre's velocity plus omega x r; its vertical part is the centre's).
Eigen::Vector3d sphere_contact_force(const ContactSphere& s, const ContactSet& set, const Eigen::Vector3d& centre_G_m,
                                     const Eigen::Vector3d& contact_point_velocity_G_m_s, double t_s = 0);

// JSON "cpgait.contact/1": {"ground_height_m": 0, "ground_velocity_m_s": [3] (a treadmill belt), "step_height_m",
// "step_x_m", "step_edge_m", "defaults": {sphere fields}, "spheres": [{"name",
// "body", "location_m": [3], "radius_m", "stiffness", "dissipation", "static_friction",
// "dynamic_friction", "viscous_friction", "transition_velocity"}]}; missing fields take "defaults",
// then the values above. Throws InputError naming the field.
ContactSet parse_contact_set_json(const std::string& text, const std::string& name, const Model& model);
ContactSet read_contact_set(const std::string& path, const Model& model);

// Every sphere's centre (ground frame, m) in every pose (rows of q_samples): element i * spheres + s
// is pose i's centre of sphere s.
std::vector<Eigen::Vector3d> sphere_centres_over_poses(const Model& model, const ContactSet& set, const Eigen::MatrixXd& q_samples);

// Puts the set's ground under recorded feet (poses q at times t, one row each), for simulations on
// spheres that follow a recorded trial:
// - height: the lowest sphere bottom over the poses, raised by how far half the body weight presses
//   one sphere in, so that the lowest foot stands rather than hovers;
// - velocity: the median horizontal velocity of each pose's lowest sphere while it is within 1 cm of
//   that ground. A treadmill trial gives the belt's (the stance foot moves backwards with it);
//   overground, under 0.1 m/s, it is zero.
void place_ground_under_feet(const Model& model, ContactSet& set, const std::vector<double>& time_s,
                             const Eigen::MatrixXd& q_samples);

// Fits foot spheres to a recorded trial so that the recorded poses load them as the ground loaded the
// subject: a foot model's soles and a marker-based IK never agree to the millimetre (on subject01
// the right heel sphere stayed 6 mm above the ground all through its stance while the left toes sank
// 5 mm - measured), and stiff spheres turn millimetres into hundreds of newtons. After
// place_ground_under_feet (height, belt):
// - each sphere's radius changes by its lowest bottom over the trial, so every sphere touches the
//   ground at its lowest (a sphere that never comes within max_lift_m of the lowest is left alone);
// - all grow by one depth, chosen so the trial's mean static sphere force (k d^1.5) equals body
//   weight, as the mean vertical GRF over whole strides does.
// The ground is left where place_ground_under_feet put it.
struct FootSphereFit {
  std::vector<double> radius_change_m;  // per sphere, in the set's order
  double depth_m = 0;                   // the common depth
  double mean_force_N = 0;              // the trial's mean sphere force at that depth
  std::vector<std::string> warnings;
};
FootSphereFit fit_foot_spheres_to_trial(const Model& model, ContactSet& set, const std::vector<double>& time_s,
                                        const Eigen::MatrixXd& q_samples, double max_lift_m = 0.03);

// Spheres on calcn_/toes_ bodies (gait2392 and its kin) or on foot_ bodies (the fixture walker), for
// simulations without GRF or contact file: two per foot (heel, toes; the default) or five (medial and
// lateral heel, first and fifth metatarsal heads, toes), named <part>_r / <part>_l. Each is levelled
// with the foot's first in the model's default pose, where the foot stands flat. Two spheres on the
// foot's midline resist no roll: subject01's walkers stood on one of them at a time and fell over
// ground steps, on five the same tuning walked them (measured: README). Throws std::invalid_argument
// for another count.
ContactSet default_foot_contacts(const Model& model, int spheres_per_foot = 2);

}  // namespace cpgait
