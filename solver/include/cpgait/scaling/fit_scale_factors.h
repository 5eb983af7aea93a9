#pragma once
// Automatic scaling, without a measurement set: the bodies' scale factors, the markers' offsets from
// their generic places and the poses of the static trial (and of frames of motion trials, when given)
// fitted together as one nonlinear least-squares problem (Ceres):
//   min  sum_f sum_m w_m |p_m(q_f; s) + R_B(q_f; s) d_m - x_m,f|^2
//      + offset_prior^2 sum_m |d_m|^2 + scale_prior_m^2 sum_b |s_b - 1|^2
// where the model is placed as scale_model scales it (scaled_forward_kinematics) and each
// marker sits at s_b (.) location_m + d_m in its body. The model is then scaled with the factors
// (scale_model) and its markers placed on the static trial (place_markers), as OpenSim's MarkerPlacer
// does after its ModelScaler; with motion trials the markers keep their fitted offsets instead (they
// are told apart from the factors by the motion). A body without markers of its own on the static
// trial takes its parent's factors.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/trc.h"
#include "cpgait/model/model.h"

namespace cpgait {

struct ScaleFitOptions {
  // One factor per body (its three axes alike, as gait2392's measurements scale) or one per body axis.
  bool per_axis = false;
  // Bodies named <name>_r and <name>_l (or _R/_L) share their factors.
  bool symmetric = true;
  // A marker's offset from its scaled generic place costs as much as this many times the same
  // marker error. Only motion frames tell offsets from scale; on one static frame it changes nothing
  // but the cost's size. Default 1.
  double offset_prior = 1.0;
  // (s - 1) costs as much as a marker error of scale_prior_m * (s - 1) metres: keeps bodies with few
  // markers near the generic size. Default 0.01 m (a 10 % change weighs like 1 mm).
  double scale_prior_m = 0.01;
  // Frames taken evenly from each motion trial. Default 10.
  int frames_per_motion_trial = 10;
  // The static trial's time range (all of it when unset); its frames are averaged into one.
  std::optional<std::pair<double, double>> static_time_range_s;
  // The subject's mass (kg); <= 0 keeps the scaled masses. Default: not given.
  double subject_mass_kg = -1;
  // Masses keep their shares of the total (OpenSim's preserve_mass_distribution). Default true.
  bool preserve_mass_distribution = true;
  int max_iterations = 100;
};

struct ScaleFitSummary {
  int frames = 0;      // static (1) plus motion frames
  int residuals = 0;   // marker observations
  int parameters = 0;  // free: poses, factors, offsets
  int iterations = 0;
  double seconds = 0;
  double static_rms_generic_m = 0;  // the static frame's marker RMS with IK on the generic model
  double static_rms_fitted_m = 0;   // the same on the fitted factors, before markers are moved
  double static_rms_placed_m = 0;   // and with the final markers (placed, or the fitted offsets)
  std::vector<std::string> warnings;
  std::string BriefReport() const;
};

struct ScaleFit {
  std::vector<Eigen::Vector3d> factors;  // per body, ground's (1, 1, 1)
  Model model;                           // scaled, markers placed on the static trial
  Eigen::VectorXd static_pose;           // rad or m
  ScaleFitSummary summary;
};

// tasks: marker weights (an IKTaskSet; every marker weight 1 when empty). Throws InputError when the
// static trial shares fewer than 3 markers with the model.
ScaleFit fit_scale_factors(const Model& generic, const MarkerTrial& static_trial, const IkTaskSet& tasks,
                           const std::vector<const MarkerTrial*>& motion_trials = {}, const ScaleFitOptions& options = {});

}  // namespace cpgait
