#pragma once
// A reproduced walk's measures from its records: heel strikes, strides, contact phases, tracking
// against the trial, drift, the stand after a stop, the mean residuals.
#include <Eigen/Core>
#include <vector>

#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait {

// A foot is on the ground while its spheres bear more than this (N), in the measures and in the
// controller's feedback (stance legs, touchdowns, the CPG's contact signals).
inline constexpr double kFootContactThresholdN = 20.0;

// Share of [t0, t1) each side was loaded (over kFootContactThresholdN), both were and neither was, in %.
struct ContactPhases {
  double stance_percent[2] = {0, 0};  // right, left
  double double_support_percent = 0, flight_percent = 0;
};
ContactPhases contact_phases(const std::vector<double>& time_s, const std::vector<double>& load_r, const std::vector<double>& load_l,
                             double t0, double t1);

// Times signal v(t) rises through threshold (interpolated between samples) and then stays at or above
// it for hold_s (or to the record's end), each at least min_gap_s after the last: a foot's landing, not a
// toe brushing the ground.
std::vector<double> rising_through(const std::vector<double>& t, const std::vector<double>& v, double threshold, double min_gap_s,
                                   double hold_s);

// Whether p lies inside the convex hull of pts (2-D, Andrew's monotone chain); on its edge counts as
// inside; fewer than three points not in a line have no inside.
bool inside_convex_hull(std::vector<Eigen::Vector2d> pts, const Eigen::Vector2d& p);

// Whether the centre of mass (kin: the pose's kinematics) lies over the feet: inside the ground-plane
// hull of the contact points bearing load (contact_force_N, contact_point_m: per sphere, ground frame),
// or for a planar model, which cannot fall sideways, between two of them along x.
bool centre_of_mass_supported(const Model& model, const KinematicsWorkspace<double>& kin, const std::vector<Eigen::Vector3d>& contact_force_N,
                              const std::vector<Eigen::Vector3d>& contact_point_m, bool planar);

// ReproducedGaitResult::drift_rad of a walk sampled at time_s (from 0, rising), q its coordinates (rows:
// samples; yaw, tx, tz: the columns of the pelvis' yaw (rad; < 0: none) and horizontal position (m)),
// on a ground moving at belt_xz_m_s (m/s, ground x and z), its gait cycle cycle_s long (s).
double walk_drift_rad(const std::vector<double>& time_s, const Eigen::MatrixXd& q, int yaw, int tx, int tz, const Eigen::Vector2d& belt_xz_m_s,
                      double cycle_s);

// The coordinates a walk's angle measures run over (its cycle change; the tuner's rotation tracking):
// every angle of the model.
std::vector<int> walk_angles(const Model& model);

// ReproducedGaitResult::cycle_change_rad: the RMS over the angles and the last cycle's samples of
// q(t) - q(t - cycle_s) (rad; 0 for a walk shorter than two cycles); time_s evenly sampled.
double walk_cycle_change_rad(const std::vector<double>& time_s, const Eigen::MatrixXd& q, const std::vector<int>& angles, double cycle_s);

// What measure_walk needs besides the records in the result.
struct WalkRecord {
  const std::vector<int>* root = nullptr;         // the root's coordinates
  const std::vector<int>* sphere_side = nullptr;  // each contact sphere's foot (0 right, 1 left, -1 neither)
  double cycle_s = 1, speed = 1;                  // the CPG's cycle at speed 1 (s), and its speed times the knob
  double tracked_until_s = 0;                     // the reference's end in simulated time, s
  double dt_s = 0;                                // the records' interval, s
  Eigen::Vector3d belt_velocity_m_s = Eigen::Vector3d::Zero();  // the ground's, ground frame
  const std::vector<double>* pelvis_speed_m_s = nullptr;  // walk -> stand: the pelvis' speed over the ground, per record
  const std::vector<char>* com_supported = nullptr;       // walk -> stand: the centre of mass over the feet, per record
  bool residuals = false;                                 // the walk had pelvis residuals
};

// The walk's measures from r's records (time_s, q, q_reference, residuals, contact_force_N), its
// frozen_at_s and fell_at_s: tracking, heel strikes, strides, contact phases, drift, the stand and
// the mean residuals, into r.
void measure_walk(const Model& model, const WalkRecord& w, ReproducedGaitResult& r);

}  // namespace cpgait
