#pragma once
// Marker-based inverse kinematics as OpenSim's IK tool: per frame, minimise
//   sum_m w_m |p_m(q) - p_m,measured|^2 + sum_c w_c (q_c - q_c,task)^2
// with Ceres (Levenberg-Marquardt, analytic Jacobian from the motion subspace), warm-started
// from the previous frame.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/model/model.h"
#include "cpgait/progress.h"

namespace cpgait {

struct IkOptions {
  // Which coordinates get their range as bounds. OpenSim bounds a coordinate only when it is
  // `clamped`; kAllRanges bounds every coordinate with a range.
  enum class Bounds { kClampedOnly, kAllRanges, kNone };
  Bounds bounds = Bounds::kClampedOnly;
  // Frames whose time lies in [first, last] (s); all frames when unset.
  std::optional<std::pair<double, double>> time_range_s;
  // Stopping rules (as Ceres names them). A relative cost change of 1e-7, for a step taken or
  // predicted, leaves the coordinates within 0.003 deg of a 1e-12 solution on gait2392 and the
  // objective at OpenSim's optimum at every frame (tests/reference/test_ik_gait2392.cpp); 1e-6 ran
  // 8 % faster but left the scale tool's placed markers 7e-6 m from OpenSim's.
  double function_tolerance = 1e-7;
  double gradient_tolerance = 1e-14;
  double parameter_tolerance = 1e-10;
  int max_iterations = 200;
  // Weight for every marker found in both model and trial when the task set lists no markers.
  double default_marker_weight = 1.0;
};

// The markers and coordinate tasks one IK run uses, resolved against a model and a trial.
struct IkTargets {
  struct MarkerTarget {
    int model_marker;
    int trial_marker;
    double weight;
  };
  struct CoordinateTarget {
    int coordinate;
    double weight;
    double value;            // rad or m, when column < 0
    int reference_column = -1;  // column of the coordinate reference table (from_file)
  };
  std::vector<MarkerTarget> markers;
  std::vector<CoordinateTarget> coordinates;
  std::vector<std::string> warnings;
};

// Throws InputError when nothing can be tracked or a task names a coordinate the model lacks.
IkTargets make_ik_targets(const Model& model, const MarkerTrial& trial, const IkTaskSet& tasks,
                          const IkOptions& options, const Storage* coordinate_reference = nullptr);

// The weighted objective at q for one frame (missing markers skipped); coordinate_reference
// rows must align with trial frames when from_file tasks exist.
double ik_objective(const Model& model, const IkTargets& targets, const MarkerTrial& trial, int frame,
                    const Eigen::VectorXd& q, const Eigen::VectorXd* reference_row = nullptr);

struct IkSummary {
  int frames = 0;
  int total_iterations = 0;
  int max_iterations_in_a_frame = 0;
  int frames_not_converged = 0;
  double solve_seconds = 0;
  double mean_marker_rms_m = 0;
  double max_marker_rms_m = 0;
  double max_marker_error_m = 0;
  std::vector<std::string> warnings;
  double frames_per_second() const { return solve_seconds > 0 ? frames / solve_seconds : 0; }
  std::string BriefReport() const;
};

struct IkResult {
  std::vector<double> time_s;
  Eigen::MatrixXd q;                    // frames x coordinates (rad or m)
  std::vector<std::string> marker_names;  // markers tracked, in target order
  Eigen::MatrixXd marker_error_m;       // frames x markers tracked; NaN where missing
  Eigen::VectorXd objective;            // weighted objective per frame
  Eigen::VectorXd total_squared_error_m2;
  Eigen::VectorXd marker_rms_m;
  Eigen::VectorXd marker_max_m;
  std::vector<int> worst_marker;        // index into marker_names, per frame
  IkSummary summary;
};

IkResult inverse_kinematics(const Model& model, const MarkerTrial& trial, const IkTaskSet& tasks,
                            const IkOptions& options = {}, const Storage* coordinate_reference = nullptr,
                            Progress* progress = nullptr);

// OpenSim-format tables: coordinates (angles in degrees) and per-frame marker errors (OpenSim's four
// columns, worst_marker, then one column per tracked marker, metres).
Storage ik_coordinates_table(const Model& model, const IkResult& result, const std::string& name = "Coordinates");
Storage ik_marker_errors_table(const IkResult& result);

}  // namespace cpgait
