#pragma once
// OpenSim's MarkerPlacer: the static trial averaged over its time range into one frame, inverse
// kinematics on that frame with the setup's tasks, and every model marker that is not `fixed` moved
// onto its measured position at that pose (in its body's frame).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/trc.h"
#include "cpgait/model/model.h"

namespace cpgait {

struct MarkerPlacement {
  Model model;                     // the markers placed
  Eigen::VectorXd static_pose;     // the coordinates IK found (rad or m)
  double time_s = 0;               // the averaged frame's time: the range's start, as OpenSim's
  int markers_moved = 0;
  double marker_rms_before_m = 0;  // at the static pose, before the markers were moved
  std::vector<std::string> warnings;  // markers left where they were (absent or gap-filled only)
};

// The static trial as one frame: each marker's mean over the frames in the range (all frames when
// unset) where it was seen, NaN where it never was; its time is the range's start, as OpenSim's.
MarkerTrial average_static_frame(const MarkerTrial& trial, const std::optional<std::pair<double, double>>& time_range_s);

MarkerPlacement place_markers(const Model& model, const MarkerTrial& static_trial, const IkTaskSet& tasks,
                              const std::optional<std::pair<double, double>>& time_range_s);

}  // namespace cpgait
