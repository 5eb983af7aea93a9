#pragma once
// The reproduced gait (the seed's applied motion): the muscle-driven model on foot-ground contact
// spheres, its muscles excited by a fitted CPG (cpg_fit.h) with the CPG's own feedback (joint
// angles, foot contact into the neurons, gains in its JSON; its phase reset at touchdowns,
// phase_resetting.h) and a spinal-reflex-like joint-angle feedback into the excitations; pelvis
// residual actuators optional and reported.
//
// Every control interval (2.5 ms): the CPG advances one step with its feedback signals; each muscle's
// excitation is the CPG's plus  kp * sum_c r_mc (q_ref,c - q_c) + kv * sum_c r_mc (u_ref,c - u_c)
// over the non-pelvis coordinates (r: moment arms, m), so a muscle that would correct a joint's
// error is excited more. Balance feedback (simbicon_balance.h), when on, moves the stance hip's and
// the swing hip's targets to right the pelvis and place the swing foot. The pelvis residuals, when
// on, hold the pelvis' rotations on the reference by computed torque and its translations by soft
// springs (see the options), so the ground, not the residuals, carries the body. The reference is the trial's kinematics, time-scaled by the speed
// knob. The feet should be fitted to the trial (fit_foot_spheres_to_trial): on subject01 the default
// spheres under the recorded poses carried a fifth of the body's weight, and with the pelvis on soft
// springs the model sank onto its toes and fell at 2.45 s (28 % BW, hip_flexion_l 21 deg off) -
// measured.
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/cpg/matsuoka.h"
#include "cpgait/cpg/phase_resetting.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/dynamics/rosenbrock_w.h"
#include "cpgait/gait/simbicon_balance.h"
#include "cpgait/gait/standing_balance.h"
#include "cpgait/model/model.h"
#include "cpgait/progress.h"

namespace cpgait {

struct ReproducedGaitOptions {
  double start_time_s = 0;        // in the reference: a heel strike of the foot the CPG was fitted to
  // Where the simulation begins in the reference (s). < 0: at start_time_s plus the CPG's start
  // phase, or earlier where the reference would end before duration_s (subject01's 2.5 s trial holds
  // two cycles, but not two after its first right heel strike). Begun off the CPG's start phase, the
  // CPG first runs on its limit cycle to the phase the reference has there.
  double begin_time_s = -1;
  double duration_s = 2.5;        // simulated time (s): at least two cycles for a gait at 1.2 s/cycle
  double speed = 1.0;             // CPG speed knob (cycle time / speed); the reference and a treadmill belt alike
  double amplitude = 1.0;         // CPG amplitude knob
  bool pelvis_residuals = true;
  // The pelvis residuals. Rotations: computed torque with these PD gains (1/s^2, 1/s). Translations:
  // springs and dampers (1/s^2, 1/s, times body mass) without feedforward, so the ground carries the
  // body: computed torque on them too held the pelvis on the trial while the residuals carried 54-79
  // % of body weight. On subject01 (feet fitted to the trial) 100 / 20 left 11.0 % BW, 30 / 11 7.9 %,
  // 10 / 6.3 5.5 % and 3 / 3.5 3.3 %, the pelvis drifting 1, 2, 3 and 4 cm RMS over the treadmill and
  // the joints unchanged (2.2-2.5 deg worst; rigid tendons, reflexes 100 / 10) - measured.
  double pelvis_kp = 100, pelvis_kv = 20;
  double pelvis_translation_kp = 10, pelvis_translation_kv = 6.3;
  // Excitation per (m x rad) and per (m x rad/s). On subject01 (muscles scaled with the model, toes
  // passive, rigid tendons, feet fitted) 100 / 10 tracked every coordinate within 2.4 deg at 5.4 % BW;
  // 200 / 20 within 1.9 deg at 5.1 %; 60 / 6 within 3.4 deg at 6.2 %; at 40 / 4 the legs gave way
  // (hip_flexion_l 27 deg off, fell at 1.55 s) - measured.
  double reflex_kp = 100, reflex_kv = 10;
  // Passive joints: a spring-damper towards the coordinate's default value on the coordinates whose
  // names start with this prefix, as a joint's ligaments and soft tissue would. gait2392's toes have
  // none: crossed only by the long toe flexors and extensors, which static optimization leaves idle
  // (the measured GRF acts on the calcaneus), they bent to 100-150 deg under the toe spheres -
  // measured. Empty prefix: none.
  // On subject01 (feet fitted to the trial) 100 N m/rad let the right toes bend 5.2 deg RMS off the
  // trial, 150 3.7 deg, 300 less than the worst joint's 2.4 deg - measured.
  std::string passive_coordinate_prefix = "mtp_";
  double passive_stiffness_Nm_per_rad = 300, passive_damping_Nms_per_rad = 0.5;
  // The controller's interval (s, default 2.5 ms, at most 10 ms): the CPG, the reflexes and the
  // balance feedback are updated once per interval and held over it (400 Hz, against activation
  // time constants of 10 ms and more); it is also the integrator's largest step and the output's
  // sample. The integrator begins anew at each, so it sets the cost: 1 ms cost subject01's walk 2.1x
  // the instructions (README, issue 22's benchmark).
  double control_interval_s = 0.0025;
  // The integrator and its error tolerance (relative and absolute). ROS34PW2 (third order, its
  // estimate second order) at 1e-3 took one step per 2.5 ms interval on subject01 and stayed within
  // 0.11 deg RMS of its 1e-5 walk over 10 s, where ROS2 at 1e-3 and 1 ms strayed 0.75 deg - measured
  // (README). ROS2 (rosenbrock_w.h) reproduces walks made before it.
  WMethod integrator = WMethod::kRos34pw2;
  double integrator_tolerance = 1e-3;
  // Rigid tendons by default: the CPG is fitted to static optimization's activations, which assume
  // them. On subject01 rigid tendons tracked within 2.4 deg at 5.4 % BW in 4.3k integrator steps,
  // compliant ones within 4.4 deg at 7.0 % BW in 13.2k - measured. Compliant (OpenSim's
  // Thelen2003Muscle) suits a CPG fitted to CMC's excitations.
  bool compliant_tendons = false;
  double fall_height_fraction = 0.75;          // pelvis height below this share of its start: fallen
  // The reflexes' targets (and the pelvis rotations', and the tracking figures'): the trial's cycle
  // average at the CPG's phase, read from its rhythm neurons (cpg_phase.h), instead of the trial at
  // the simulation's time, so that the speed knob and entrainment move them with the CPG. The pelvis
  // translations keep the trial's. Needs a full cycle of reference after start_time_s. Default off.
  bool phase_indexed_reference = false;
  // The CPG's entrainment by phase resetting at foot contact (phase_resetting.h; a touchdown is a
  // foot's spheres coming to bear over 20 N); its share 0 (the default) runs the rhythm open loop.
  PhaseResettingOptions entrainment;
  // Balance feedback into the reflex (simbicon_balance.h); off by default. The reference pose it
  // compares against is the reflexes'; the reference velocity the trial's mean pelvis velocity.
  SimbiconGains balance;
  // Robustness trials. A push: a force at the pelvis' origin (N, ground frame) from push_time_s (s;
  // < 0: none) for push_duration_s (s, default 0.1), its impulse force x duration.
  double push_time_s = -1, push_duration_s = 0.1;
  Eigen::Vector3d push_force_N = Eigen::Vector3d::Zero();
  // A step in the ground (m; negative: down; default 0: level) whose edge reaches the pelvis'
  // starting place at ground_step_time_s (s) - carried there by the belt on a treadmill, walked to at
  // the trial's mean speed overground. The trial is taken to walk along ground x.
  double ground_step_m = 0, ground_step_time_s = 5;
  // Walk -> stand: from stop_time_s (s; < 0: never) the walk goes on until the cycle's phase (the
  // CPG's; 0 at its foot's heel strike) reaches stop_phase, then stops there. The CPG stops and its
  // excitations fade to the muscles' minimum over stand_fade_s (s; default 0.3); the reflexes' targets
  // turn from the pose at that phase to a standing pose (standing_pose.h) over stand_blend_s (s;
  // default 0.3), the trunk feedback fading out alike; the standing balance (standing_balance.h,
  // gains `standing`) acts from the stop on; a treadmill's belt slows to a halt over stop_over_s (s;
  // <= 0: 0.3). Stopped at the CPG foot's mid-stance (default 0.3) the body is over that foot and the
  // other one swings in beside it. The stop's test gives what was tried.
  double stop_time_s = -1, stop_over_s = 0, stop_phase = 0.3;
  double stand_blend_s = 0.3, stand_fade_s = 0.3;
  // Standing, the joint reflex's gains (reflex_kp, reflex_kv) rise to this many times the walk's over
  // stand_blend_s (default 2): with the CPG faded the reflexes alone hold the pose against gravity,
  // and a controller tuned to walk on soft reflexes buckles at its walking gains (the stop's test).
  double stand_reflex_gain = 2;
  StandingBalanceGains standing;
  // The walk's state at the control interval that begins at this time (s; < 0, the default: none) is
  // kept in the result (ReproducedGaitResult::checkpoint), for a walk that is this one until then to
  // resume from. Not after a stop_time_s.
  double checkpoint_at_s = -1;
};

// A walk's state at the start of a control interval, and what it recorded before: the simulation
// loop's whole state, so a walk resumed from it is the walk taken from the beginning, to the bit.
struct ReproducedGaitCheckpoint {
  int interval = 0;  // the control interval it begins (time interval x control_interval_s)
  double time_s = 0;
  Eigen::VectorXd x, excitation;
  MatsuokaState neurons;
  PhaseResetting resetting{PhaseResettingOptions{}};
  double integrator_step_s = 0;  // the integrator's next step
  long integrator_steps = 0;
  std::vector<double> time_rec_s;
  std::vector<Eigen::VectorXd> q, q_reference, residuals, excitations, contact_force_N;
};

struct ReproducedGaitResult {
  std::vector<std::string> coordinate_names;
  double reference_begin_s = 0;                // the reference's time at simulated time 0
  std::vector<double> time_s;                  // simulated time from 0
  Eigen::MatrixXd q, q_reference;              // samples x coordinates (rad, m)
  Eigen::MatrixXd residuals;                   // samples x 6: pelvis generalized forces (N m, N)
  std::vector<std::string> residual_names;
  Eigen::MatrixXd excitations;                 // samples x muscles
  std::vector<std::string> contact_names;
  Eigen::MatrixXd contact_force_N;             // samples x 3 per sphere (ground frame)
  // Metrics.
  Eigen::VectorXd tracking_rms;                // per coordinate (rad, m)
  Eigen::VectorXd tracking_rms_first_two_cycles;  // the same over the first two CPG cycles (cycle / speed)
  double worst_rotation_rms_rad = 0;
  std::string worst_rotation;
  std::vector<double> heel_strikes_r_s, heel_strikes_l_s;
  double stride_time_s = 0, stride_length_m = 0, speed_m_s = 0;  // means over full strides
  // Contact phases over the full right strides, % of their time: a foot is loaded while its spheres
  // bear over 20 N, double support while both are, flight while neither is (0 without two right heel
  // strikes). Walking typically: stance ~60 %, double support ~20 % (subject01's force plates: 24 %),
  // no flight; running: stance under 50 %, no double support, flight.
  double stance_percent_r = 0, stance_percent_l = 0, double_support_percent = 0, flight_percent = 0;
  double mean_residual_force_percent_bw = 0;   // |pelvis residual force| mean, % of body weight
  double mean_residual_moment_Nm = 0;
  double fell_at_s = -1;                        // < 0: did not fall
  double distance_m = 0;                        // pelvis horizontal travel
  // How far the walk's cycle-mean walking direction (over the belt) and pelvis yaw moved from the
  // cycle that ends halfway through it to its last cycle, the two summed (rad; 0 for a walk shorter
  // than two cycles, a walk that stopped (stop_time_s) or a model without pelvis_tx and pelvis_tz; no
  // yaw without pelvis_rotation). A walk settled on its limit cycle keeps both, straight or not;
  // subject01's tuned walkers that drifted fell soon after (docs/gait-tuning.md).
  double drift_rad = 0;
  // How far the walk's last cycle is from the one before: the RMS over its angles of q(t) - q(t -
  // cycle / speed) (rad; 0 for a walk shorter than two cycles or one that stopped). A walk on a stable
  // limit cycle repeats itself; one on its way to a fall does not.
  double cycle_change_rad = 0;
  // The CPG's entrainment (ReproducedGaitOptions::entrainment), and the touchdowns that reset its phase.
  PhaseResettingOptions entrainment;
  int entrainment_resets = 0;
  // Walk -> stand (stop_time_s): when the walk froze, and the longest stretch after it with the
  // pelvis at rest (horizontal speed over the ground below 0.1 m/s) and the centre of mass over the
  // support polygon of the loaded contact spheres (a planar model's: between them along x): when it
  // began (< 0: never) and how long it lasted.
  double frozen_at_s = -1;
  double stopped_at_s = -1, stood_s = 0;
  double solve_seconds = 0;
  long integrator_steps = 0;
  std::vector<std::string> warnings;
  // The state at options.checkpoint_at_s, where the walk got there; resumed_at_s: where this walk
  // resumed from a checkpoint (0: it began at the beginning). solve_seconds is this call's time.
  std::shared_ptr<const ReproducedGaitCheckpoint> checkpoint;
  double resumed_at_s = 0;
  double real_time_factor() const { return solve_seconds > 0 && !time_s.empty() ? (time_s.back() - resumed_at_s) / solve_seconds : 0; }
  std::string BriefReport() const;
};

// Where in the reference (s) a simulation with these options begins: begin_time_s if given, else the
// heel strike plus the CPG's start phase, or earlier where the reference would end before duration_s.
double reproduced_gait_begin_s(const CpgModel& cpg, double reference_front_s, double reference_end_s, const ReproducedGaitOptions& o);

// The options with a tuned controller applied (tune_gait_controller.h; stored in the CPG's JSON): its
// reflex and balance gains, reference, residual setting, start and beginning, and the simulation it
// was tuned in where it records one.
ReproducedGaitOptions with_controller(const CpgController& controller, ReproducedGaitOptions options);
// That simulation alone: the controller's interval, the integrator and its tolerance, where recorded.
ReproducedGaitOptions with_controller_simulation(const CpgController& controller, ReproducedGaitOptions options);
// Records the options' simulation in the controller (CpgController::control_interval_s...).
void record_simulation(const ReproducedGaitOptions& options, CpgController& controller);

// resume_from: a checkpoint of a walk with the same model, CPG, reference, contacts and options up
// to its time (a stop or a push may follow it, not precede it); the walk goes on from there.
ReproducedGaitResult reproduce_gait(const Model& model, const CpgModel& cpg, const Storage& reference_coordinates,
                                    const ContactSet& contacts, const ReproducedGaitOptions& options = {},
                                    Progress* progress = nullptr, const ReproducedGaitCheckpoint* resume_from = nullptr);

// Files: the simulated motion (.mot, degrees), the residuals (.sto), contact forces (.sto), and the
// metrics as JSON.
Storage reproduced_gait_motion_table(const Model& model, const ReproducedGaitResult& r);
Storage reproduced_gait_residual_table(const ReproducedGaitResult& r);
Storage reproduced_gait_contact_table(const ReproducedGaitResult& r);
nlohmann::json reproduced_gait_metrics(const Model& model, const ReproducedGaitResult& r);
// Its "contact_phases": {"stance_percent": {"right", "left"}, "double_support_percent", "flight_percent"}.
nlohmann::json reproduced_gait_contact_phases(const ReproducedGaitResult& r);

}  // namespace cpgait
