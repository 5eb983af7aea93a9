#include "cpgait/scaling/model_scale_factors.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

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
      // OpenSim only prints a warning and leaves the bodies unscaled, which users rarely notice.
      if (!missing.empty()) throw InputError(where, meas.line, "Measurement '" + meas.name + "'", missing);
      if (meas.marker_pairs.empty() || !std::isfinite(sum))
        throw InputError(where, meas.line, "Measurement '" + meas.name + "'",
                         meas.marker_pairs.empty() ? "no marker pairs" : "the markers' distances are not finite over the time range");
      const double factor = sum / static_cast<double>(meas.marker_pairs.size());
      if (!(factor >= kMinScaleFactor && factor <= kMaxScaleFactor)) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "scale factor %.4g is outside %.1f-%.1f: check the static trial's units and marker names",
                      factor, kMinScaleFactor, kMaxScaleFactor);
        throw InputError(where, meas.line, "Measurement '" + meas.name + "'", buf);
      }
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

std::string scale_set_document(const Model& model, const std::vector<Eigen::Vector3d>& factors) {
  std::string out = "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40000\">\n\t<ScaleSet name=\"ScaleSet\">\n\t\t<objects>\n";
  char buf[128];
  for (std::size_t b = 0; b < model.bodies.size() && b < factors.size(); ++b) {
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g", factors[b][0], factors[b][1], factors[b][2]);
    out += "\t\t\t<Scale>\n\t\t\t\t<scales>" + std::string(buf) + "</scales>\n\t\t\t\t<segment>" + model.bodies[b].name +
           "</segment>\n\t\t\t\t<apply>true</apply>\n\t\t\t</Scale>\n";
  }
  return out + "\t\t</objects>\n\t\t<groups />\n\t</ScaleSet>\n</OpenSimDocument>\n";
}

}  // namespace cpgait
