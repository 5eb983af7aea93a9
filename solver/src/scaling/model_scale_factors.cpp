#include "cpgait/scaling/model_scale_factors.h"

#include <algorithm>
#include <cmath>

#include "cpgait/capture/input_error.h"
#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait {

ModelScaleFactors model_scale_factors(const Model& model, const ScaleSetup& setup, const MarkerTrial* trial) {
  ModelScaleFactors r;
  r.body.assign(model.bodies.size(), Eigen::Vector3d::Ones());
  const std::string& where = setup.file;
  // As OpenSim's: a scale for a body the model does not have changes nothing (it is said, once).
  auto body_of = [&](const std::string& name) {
    const int b = model.body_index(name);
    if (b < 0) {
      const std::string w = "the model has no body '" + name + "': its scale factor is not used";
      if (std::find(r.warnings.begin(), r.warnings.end(), w) == r.warnings.end()) r.warnings.push_back(w);
    }
    return b;
  };
  // The model's marker distances in its default pose.
  KinematicsWorkspace<double> ws(model);
  const Eigen::VectorXd q0 = model.default_coordinates();
  forward_kinematics(model, q0.data(), ws);
  for (const std::string& step : setup.scaling_order) {
    if (step == "manualScale") {
      for (const auto& m : setup.manual_scales)
        if (const int b = body_of(m.body); b >= 0) r.body[b] = Eigen::Vector3d(m.factors[0], m.factors[1], m.factors[2]);
      continue;
    }
    if (!trial) throw InputError(where, 0, "marker_file", "measurements need the static trial (marker_file)");
    int first = 0, last = trial->num_frames() - 1;
    if (setup.time_range_s) {
      const auto [t0, t1] = *setup.time_range_s;
      for (int i = trial->num_frames() - 1; i >= 0; --i)
        if (trial->time_s[i] <= t0) {
          first = i;
          break;
        }
      for (int i = first; i < trial->num_frames(); ++i)
        if (trial->time_s[i] >= t1 - 1e-15) {
          last = i;
          break;
        }
    }
    for (const auto& meas : setup.measurements) {
      double sum = 0;
      std::string missing;
      for (const auto& [a, b] : meas.marker_pairs) {
        const int ma = model.marker_index(a), mb = model.marker_index(b);
        const int ta = trial->marker_index(a), tb = trial->marker_index(b);
        if (ma < 0 || mb < 0) missing = "marker " + (ma < 0 ? a : b) + " is not in the model";
        else if (ta < 0 || tb < 0) missing = "marker " + (ta < 0 ? a : b) + " is not in " + trial->name;
        if (!missing.empty()) break;
        const double model_length = (marker_position(model, ma, ws) - marker_position(model, mb, ws)).norm();
        double trial_length = 0;
        for (int f = first; f <= last; ++f) trial_length += (trial->position_m(f, tb) - trial->position_m(f, ta)).norm();
        trial_length /= (last - first + 1);
        sum += trial_length / model_length;
      }
      if (!missing.empty() || meas.marker_pairs.empty() || !std::isfinite(sum)) {
        r.warnings.push_back("measurement '" + meas.name + "' not used: " +
                             (missing.empty() ? std::string("no finite marker distances") : missing));
        continue;
      }
      const double factor = sum / static_cast<double>(meas.marker_pairs.size());
      r.measured.emplace_back(meas.name, factor);
      for (const auto& [body, axes] : meas.body_axes) {
        const int b = body_of(body);
        if (b < 0) continue;
        for (int k = 0; k < 3; ++k)
          if (axes[k]) r.body[b][k] = factor;
      }
    }
  }
  return r;
}

}  // namespace cpgait
