#include "cpgait/scaling/place_markers.h"

#include <cmath>

#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait {

MarkerTrial average_static_frame(const MarkerTrial& trial, const std::optional<std::pair<double, double>>& time_range_s) {
  const int nm = trial.num_markers();
  double t0 = trial.time_s.front(), t1 = trial.time_s.back();
  if (time_range_s) t0 = time_range_s->first, t1 = time_range_s->second;
  MarkerTrial avg;
  avg.name = trial.name;
  avg.marker_names = trial.marker_names;
  avg.time_s = {t0};  // OpenSim's averaged frame takes the range's start time
  avg.frame_numbers = {1};
  avg.data_rate_hz = avg.camera_rate_hz = trial.data_rate_hz;
  avg.positions_m.setConstant(3, nm, std::numeric_limits<double>::quiet_NaN());
  for (int m = 0; m < nm; ++m) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int n = 0;
    for (int f = 0; f < trial.num_frames(); ++f) {
      if (trial.time_s[f] < t0 - 1e-9 || trial.time_s[f] > t1 + 1e-9) continue;
      const Eigen::Vector3d p = trial.position_m(f, m);
      if (!p.allFinite()) continue;
      sum += p;
      ++n;
    }
    if (n) avg.positions_m.col(m) = sum / n;
  }
  return avg;
}

MarkerPlacement place_markers(const Model& model, const MarkerTrial& trial, const IkTaskSet& tasks,
                              const std::optional<std::pair<double, double>>& time_range_s) {
  MarkerPlacement r;
  r.model = model;
  const MarkerTrial avg = average_static_frame(trial, time_range_s);
  r.time_s = avg.time_s[0];
  const IkResult ik = inverse_kinematics(model, avg, tasks, IkOptions{});
  r.static_pose = ik.q.row(0).transpose();
  KinematicsWorkspace<double> ws(model);
  forward_kinematics(model, r.static_pose.data(), ws);
  double sum2 = 0;
  int seen = 0;
  for (auto& mk : r.model.markers) {
    const int t = avg.marker_index(mk.name);
    if (t < 0 || !avg.positions_m.col(t).allFinite()) {
      r.warnings.push_back("marker " + mk.name + " is not in " + trial.name + ": left where it was");
      continue;
    }
    const auto& B = ws.body_in_ground[mk.body];
    const Eigen::Vector3d measured = avg.positions_m.col(t);
    sum2 += (B.rotation * mk.location_m + B.translation_m - measured).squaredNorm();
    ++seen;
    if (mk.fixed) continue;
    mk.location_m = B.rotation.transpose() * (measured - B.translation_m);
    ++r.markers_moved;
  }
  r.marker_rms_before_m = seen ? std::sqrt(sum2 / seen) : 0.0;
  return r;
}

}  // namespace cpgait
