#pragma once
// The reproduced gait (the seed's applied motion): the muscle-driven model on foot-ground contact
// spheres, its muscles excited by a fitted CPG (cpg_fit.h) with the CPG's own feedback (joint
// angles, foot contact into the neurons, gains in its JSON) and a spinal-reflex-like joint-angle
// feedback into the excitations; pelvis residual actuators optional and reported.
//
// Every control interval (1 ms): the CPG advances one step with its feedback signals; each muscle's
// excitation is the CPG's plus  kp * sum_c r_mc (q_ref,c - q_c) + kv * sum_c r_mc (u_ref,c - u_c)
// over the non-pelvis coordinates (r: moment arms, m), so a muscle that would correct a joint's
// error is excited more; the pelvis residuals, when on, are the generalized forces on the pelvis'
// six coordinates that give them the reference's accelerations plus PD terms (computed torque on the
// root alone). The reference is the trial's kinematics, time-scaled by the speed knob.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/model/model.h"
#include "cpgait/progress.h"

namespace cpgait {

struct ReproducedGaitOptions {
  double start_time_s = 0;        // in the reference: a heel strike of the foot the CPG was fitted to
  double duration_s = 2.5;        // simulated time (s): at least two cycles for a gait at 1.2 s/cycle
  double speed = 1.0;             // CPG speed knob (cycle time / speed); the reference and a treadmill belt alike
  double amplitude = 1.0;         // CPG amplitude knob
  bool pelvis_residuals = true;
  double pelvis_kp = 100, pelvis_kv = 20;      // 1/s^2, 1/s on the pelvis' errors
  // Excitation per (m x rad) and per (m x rad/s). On subject01 (muscles scaled with the model, toes
  // passive, rigid tendons) 100 / 10 tracked every coordinate within 3.4 deg; 60 / 6 within 4.7 deg;
  // 40 / 4 let subtalar_l drift 18 deg; 150 / 15 to 300 / 30 tracked closer (2.6-2.1 deg) but pushed
  // the pelvis residual from 79 to 84-91 % BW, and at 300 / 30 the stride grew to 1.51 s - measured.
  double reflex_kp = 100, reflex_kv = 10;
  // Passive joints: a spring-damper towards the coordinate's default value on the coordinates whose
  // names start with this prefix, as a joint's ligaments and soft tissue would. gait2392's toes have
  // none: crossed only by the long toe flexors and extensors, which static optimization leaves idle
  // (the measured GRF acts on the calcaneus), they bent to 100-150 deg under the toe spheres -
  // measured. Empty prefix: none.
  std::string passive_coordinate_prefix = "mtp_";
  double passive_stiffness_Nm_per_rad = 100, passive_damping_Nms_per_rad = 0.5;
  double control_interval_s = 0.001;
  // ROS2's error tolerance (relative and absolute). On subject01 (rigid tendons) the motion at 1e-3
  // stays within 0.23 deg RMS of a 1e-5 run (66k steps) in 4.7k steps; 2e-3 drifts 0.41 deg in 3.1k,
  // 3e-3 0.50 deg in 2.7k - measured.
  double integrator_tolerance = 1e-3;
  // Rigid tendons by default: the CPG is fitted to static optimization's activations, which assume
  // them. On subject01 rigid tendons tracked within 3.4 deg at every speed knob setting (compliant:
  // 4.4 deg, and 20-25 deg at speed 1.2), strode 1.237 s against the trial's 1.234 s (1.20 s) and
  // took 4.7k integrator steps instead of 11.8k - measured. Compliant (OpenSim's Thelen2003Muscle)
  // suits a CPG fitted to CMC's excitations.
  bool compliant_tendons = false;
  double fall_height_fraction = 0.75;          // pelvis height below this share of its start: fallen
};

struct ReproducedGaitResult {
  std::vector<std::string> coordinate_names;
  std::vector<double> time_s;                  // simulated time from 0
  Eigen::MatrixXd q, q_reference;              // samples x coordinates (rad, m)
  Eigen::MatrixXd residuals;                   // samples x 6: pelvis generalized forces (N m, N)
  std::vector<std::string> residual_names;
  Eigen::MatrixXd excitations;                 // samples x muscles
  std::vector<std::string> contact_names;
  Eigen::MatrixXd contact_force_N;             // samples x 3 per sphere (ground frame)
  // Metrics.
  Eigen::VectorXd tracking_rms;                // per coordinate (rad, m)
  double worst_rotation_rms_rad = 0;
  std::string worst_rotation;
  std::vector<double> heel_strikes_r_s, heel_strikes_l_s;
  double stride_time_s = 0, stride_length_m = 0, speed_m_s = 0;  // means over full strides
  double mean_residual_force_percent_bw = 0;   // |pelvis residual force| mean, % of body weight
  double mean_residual_moment_Nm = 0;
  double fell_at_s = -1;                        // < 0: did not fall
  double distance_m = 0;                        // pelvis horizontal travel
  double solve_seconds = 0;
  long integrator_steps = 0;
  std::vector<std::string> warnings;
  double real_time_factor() const { return solve_seconds > 0 && !time_s.empty() ? time_s.back() / solve_seconds : 0; }
  std::string BriefReport() const;
};

ReproducedGaitResult reproduce_gait(const Model& model, const CpgModel& cpg, const Storage& reference_coordinates,
                                    const ContactSet& contacts, const ReproducedGaitOptions& options = {},
                                    Progress* progress = nullptr);

// Files: the simulated motion (.mot, degrees), the residuals (.sto), contact forces (.sto), and the
// metrics as JSON.
Storage reproduced_gait_motion_table(const Model& model, const ReproducedGaitResult& r);
Storage reproduced_gait_residual_table(const ReproducedGaitResult& r);
Storage reproduced_gait_contact_table(const ReproducedGaitResult& r);
nlohmann::json reproduced_gait_metrics(const Model& model, const ReproducedGaitResult& r);

}  // namespace cpgait
