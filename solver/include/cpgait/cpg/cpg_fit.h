#pragma once
// Fitting a Matsuoka network to muscle patterns over a gait cycle, and running it.
//
// Two layers of Matsuoka neurons. The rhythm layer is K mutually inhibiting pairs with inhibitory
// couplings between pairs: it sets the cycle. The pattern layer gives every active muscle its own few
// neurons (two by default, not coupled to each other), driven by the rhythm neurons through signed
// couplings (a negative a_ij excites); their rectified outputs, with adaptation, shape bursts at any
// phase and width, which the rhythm neurons' broad half-waves alone cannot. Each muscle's excitation
// is a non-negative combination of its pattern neurons (or, without a pattern layer, of the rhythm
// neurons) plus a non-negative bias; for given neurons that map is exact (non-negative least squares).
// So Ceres searches only dimensionless neuron parameters: first the rhythm layer with the pattern's
// phase (multiple starts, in parallel), then each muscle's pattern neurons against the fixed rhythm
// (independent small problems, in parallel); the time constants are then scaled so that the
// network's period equals the gait cycle.
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cpgait/cpg/matsuoka.h"

namespace cpgait {

// The reproduced gait's controller as tuned for this CPG (tune_gait_controller.h): stored with the CPG
// so that replaying it walks the same way.
struct CpgController {
  double reflex_kp = 100, reflex_kv = 10;  // joint reflex, excitation per (m x rad) and per (m x rad/s)
  bool phase_reference = true;             // reflex targets from the trial's cycle at the CPG's phase
  bool pelvis_residuals = false;           // tuned to walk without them
  // Balance feedback (simbicon_balance.h): stance-hip trunk shares; swing-foot placement gains across
  // and along the way (m/m, s).
  double trunk_kp = 0, trunk_kv = 0, lateral_d = 0, lateral_v = 0, sagittal_d = 0, sagittal_v = 0;
  // The heel strike (s, in the trial) the walks it was tuned on began from; < 0: unknown. A replay
  // begins there: the tuned walk is that sensitive (begun 19 ms earlier, at Zeni's heel strike rather
  // than the force plate's, subject01's fell at 5.6 s instead of walking 15 s - measured).
  double start_time_s = -1;
  // Where in the trial (s) those walks began; < 0: unknown. Without it a replay shorter or longer than
  // the tuning's horizon could begin elsewhere (a walk that would run past the trial begins earlier).
  double begin_time_s = -1;
  double speed = 1.0;  // the speed knob (ReproducedGaitOptions::speed) it was tuned at
  // The feet it was tuned on: default_foot_contacts' spheres per foot (2 or 5), 0 for a contact file's.
  // A replay stands on them unless told otherwise; on other feet a tuned walk is another walk.
  int foot_spheres = 2;
  // Phase resetting at foot contact (ReproducedGaitOptions::entrainment): the share 0-1 of the phase
  // error made up (default 0: none), and the right and left feet's heel-strike phases (0, 0.5).
  double entrainment = 0, entrainment_phase_r = 0, entrainment_phase_l = 0.5;
  // The simulation it was tuned in (ReproducedGaitOptions): the controller's interval (s), the
  // integrator (w_method_name: "ros34pw2", "rosenbrock" or "linearly_implicit_euler") and its
  // tolerance. A replay runs in it unless told otherwise: updated at another interval it is another
  // controller, and a closed-loop walk tuned at one tolerance may fall at another. 0 and empty: not
  // recorded (CPG JSONs before 2026-11-29).
  double control_interval_s = 0, integrator_tolerance = 0;
  std::string integrator{};  // initialised, so that designated initialisers may leave it out without a warning
  // The balance feedback's stance-foot hold across the way (m/m, s) and the swing hip's world-frame
  // share (SimbiconGains; default 0: off).
  double stance_lateral_d = 0, stance_lateral_v = 0, swing_world = 0;
  // The lateral ankle strategy's gains (SimbiconGains::ankle_d, rad/m, and ankle_v, rad s/m; default 0: off).
  double ankle_d = 0, ankle_v = 0;

  nlohmann::json to_json() const;  // the CPG JSON's "controller" (CpgModel::from_json reads it)
};

// A controller tuned at another speed knob (controller.speed), with the CPG amplitude it was tuned with.
struct ScheduledController {
  CpgController controller;
  double amplitude = 1.0;
};

struct CpgModel {
  MatsuokaNetwork network;              // time constants in seconds, fitted period = cycle_s
  Eigen::MatrixXd output_map;           // muscles x neurons, >= 0
  Eigen::VectorXd output_bias;          // per muscle, >= 0
  std::vector<std::string> muscle_names;
  double cycle_s = 1.0;                 // the gait cycle it reproduces at speed 1
  double phase_at_start = 0.0;          // cycle phase (0-1) of the network's state `start`
  MatsuokaState start;                  // a state on the limit cycle
  // Knobs: speed scales all rates (cycle time / speed); amplitude scales the excitations.
  double speed = 1.0;
  double amplitude = 1.0;
  // Feedback: neuron input u = feedback_gains * signals (joint angles in rad, foot contact 0/1).
  std::vector<std::string> feedback_signals;
  Eigen::MatrixXd feedback_gains;       // neurons x signals
  std::optional<CpgController> controller;  // absent until tuned; tuned with `amplitude`
  // Controllers tuned at other speed knobs, by knob: a gait at knob k walks with the tuned knobs'
  // nearest two interpolated (scheduled_at_speed), as one controller did not walk subject01 at both
  // 0.8 and 1.2. Empty: `controller` at every knob.
  std::vector<ScheduledController> speed_schedule;

  nlohmann::json to_json() const;
  // Throws InputError naming the JSON field.
  static CpgModel from_json(const nlohmann::json& j, const std::string& source);
};

struct CpgFitOptions {
  int pairs = 2;               // rhythm-layer oscillator pairs (2 K neurons)
  // Rhythm-layer starts (the first: Matsuoka's classic pairs in a ring; the others random) and Ceres
  // iterations per start. Cores the starts leave idle share each start's differences; random starts
  // rarely did better than the ring.
  int starts = 1;
  int max_iterations = 30;
  int phase_samples = 100;     // samples per cycle of the target patterns
  double active_threshold = 0.05;  // muscles whose peak exceeds this count in the mean R^2
  int pattern_units = 2;       // pattern neurons per active muscle (0: muscles read the rhythm layer)
  int pattern_starts = 4;      // optimisation starts per muscle's pattern neurons
  unsigned seed = 1;
};

struct CpgFitSummary {
  Eigen::VectorXd r_squared;   // per muscle
  double mean_r_squared_active = 0;
  int active_muscles = 0;
  double seconds = 0;
  double rhythm_seconds = 0;   // of which: the rhythm layer's fit
  int best_start = 0;
  std::string BriefReport() const;
};

struct CpgFitResult {
  CpgModel model;
  Eigen::MatrixXd target;      // phase_samples x muscles (the cycle-averaged patterns)
  Eigen::MatrixXd fitted;      // the same, from the fitted network
  CpgFitSummary summary;
};

// The CPG as it walks at speed knob `knob`: its controller and amplitude interpolated between those
// tuned at the nearest knobs below and above (its controller's and its speed_schedule's; reflex gains
// and amplitude geometrically, balance gains and entrainment linearly; held beyond the ends). The start and
// beginning stay the controller's. Unchanged without a schedule or a controller.
CpgModel scheduled_at_speed(const CpgModel& cpg, double knob);

// Times (s) where a force column rises through threshold_N: heel strikes from a force plate's
// vertical force.
std::vector<double> contact_onsets(const Eigen::VectorXd& time_s, const Eigen::VectorXd& force_N, double threshold_N = 20.0);

// Each cycle between consecutive cycle starts (heel strikes) lying inside `time`, resampled by linear
// interpolation to `samples` phases: k / samples of the cycle, or k / (samples - 1) with include_end
// (0 to 100 % inclusive, as gait-cycle plots show them). One samples x columns matrix per cycle.
std::vector<Eigen::MatrixXd> cycle_curves(const std::vector<double>& time, const Eigen::MatrixXd& patterns,
                                          const std::vector<double>& cycle_starts_s, int samples, bool include_end = false);

// Averages patterns (samples x muscles at `time`) over the cycles between consecutive cycle starts
// (heel strikes), resampled to `samples` phases. Throws InputError with fewer than two starts
// inside the data.
Eigen::MatrixXd cycle_average(const std::vector<double>& time, const Eigen::MatrixXd& patterns,
                              const std::vector<double>& cycle_starts_s, int samples);

// Mean duration (s) of the cycles cycle_average uses (those lying inside `time`); 0 when none.
// cycles receives how many there are.
double mean_cycle_duration(const std::vector<double>& time, const std::vector<double>& cycle_starts_s, int* cycles = nullptr);

CpgFitResult fit_cpg(const Eigen::MatrixXd& cycle_patterns, double cycle_s, const std::vector<std::string>& muscle_names,
                     const CpgFitOptions& options = {});

// Runs the model for duration_s from its start state: neuron outputs (steps x neurons) and muscle
// excitations (steps x muscles, clamped to [0, 1]) at times k * dt_s. feedback: steps x signals, or empty.
struct CpgRun {
  std::vector<double> time_s;
  Eigen::MatrixXd neurons, excitations;
};
CpgRun run_cpg(const CpgModel& model, double duration_s, double dt_s, const Eigen::MatrixXd& feedback = Eigen::MatrixXd());

// The network with the speed knob applied (time constants / speed), and the muscle excitations for
// neuron outputs y (amplitude applied, clamped to [0, 1]): what run_cpg steps, for callers that step
// the network themselves (the reproduced gait closes its feedback loop that way).
MatsuokaNetwork network_at_speed(const CpgModel& model);
Eigen::VectorXd cpg_excitations(const CpgModel& model, const Eigen::VectorXd& y);
// The same with the output map given sparse (model.output_map.sparseView(): fitted maps are ~1 %
// non-zero), for callers that evaluate it every millisecond.
Eigen::VectorXd cpg_excitations(const CpgModel& model, const Eigen::VectorXd& y, const Eigen::SparseMatrix<double>& output_map);

// A smooth change from model a to model b (same structure) over [t0, t1]: parameters blend with a
// cosine ramp, e.g. walk -> faster walk, walk -> stand (amplitude 0).
CpgRun run_cpg_transition(const CpgModel& a, const CpgModel& b, double t0_s, double t1_s, double duration_s, double dt_s);

// The coefficient of determination of y against its fit.
double r_squared(const Eigen::VectorXd& y, const Eigen::VectorXd& fit);

}  // namespace cpgait
