#include "cpgait/muscles/scale_muscle_parameters.h"

#include <algorithm>
#include <cstdio>

#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/muscles/muscle_path.h"

namespace cpgait {
namespace {

std::vector<double> path_lengths_at_default_pose(const Model& model) {
  const Eigen::VectorXd q = model.default_coordinates();
  KinematicsWorkspace<double> ws(model);
  forward_kinematics(model, q.data(), ws);
  std::vector<double> lengths;
  for (const auto& mu : model.muscles) lengths.push_back(path_length(model, mu, q.data(), ws));
  return lengths;
}

}  // namespace

std::string MuscleScalingSummary::BriefReport() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%d muscles scaled by their path length ratio (%.3f to %.3f)", muscles_scaled, smallest_ratio,
                largest_ratio);
  std::string s = buf;
  if (!not_in_generic.empty()) s.append("; " + std::to_string(not_in_generic.size()) + " not in the generic model, left as they were");
  return s;
}

Model scale_muscle_parameters(const Model& scaled, const Model& generic, MuscleScalingSummary* summary) {
  Model out = scaled;
  MuscleScalingSummary s;
  s.smallest_ratio = 1e30;
  s.largest_ratio = -1e30;
  const std::vector<double> after = path_lengths_at_default_pose(scaled), before = path_lengths_at_default_pose(generic);
  for (std::size_t m = 0; m < out.muscles.size(); ++m) {
    Muscle& mu = out.muscles[m];
    const auto g = std::find_if(generic.muscles.begin(), generic.muscles.end(), [&](const Muscle& x) { return x.name == mu.name; });
    const double pre = g == generic.muscles.end() ? 0.0 : before[g - generic.muscles.begin()];
    if (!(pre > 0)) {
      s.not_in_generic.push_back(mu.name);
      continue;
    }
    const double ratio = after[m] / pre;
    mu.optimal_fiber_length_m *= ratio;
    mu.tendon_slack_length_m *= ratio;
    s.smallest_ratio = std::min(s.smallest_ratio, ratio);
    s.largest_ratio = std::max(s.largest_ratio, ratio);
    ++s.muscles_scaled;
  }
  if (s.muscles_scaled == 0) s.smallest_ratio = s.largest_ratio = 1;
  // Path springs' resting lengths likewise (OpenSim's PathSpring::extendPostScale).
  const Eigen::VectorXd q_scaled = scaled.default_coordinates(), q_generic = generic.default_coordinates();
  KinematicsWorkspace<double> ws_scaled(scaled), ws_generic(generic);
  forward_kinematics(scaled, q_scaled.data(), ws_scaled);
  forward_kinematics(generic, q_generic.data(), ws_generic);
  for (PathSpring& ps : out.path_springs) {
    const auto g = std::find_if(generic.path_springs.begin(), generic.path_springs.end(), [&](const PathSpring& x) { return x.name == ps.name; });
    if (g == generic.path_springs.end()) continue;
    const double pre = path_length(generic, *g, q_generic.data(), ws_generic);
    if (pre > 0) ps.resting_length_m *= path_length(scaled, ps, q_scaled.data(), ws_scaled) / pre;
  }
  if (summary) *summary = s;
  return out;
}

std::vector<double> normalized_fiber_lengths_at_default_pose(const Model& model) {
  std::vector<double> l = path_lengths_at_default_pose(model);
  for (std::size_t m = 0; m < l.size(); ++m) {
    const Muscle& mu = model.muscles[m];
    l[m] = mu.optimal_fiber_length_m > 0 ? (l[m] - mu.tendon_slack_length_m) / mu.optimal_fiber_length_m : 0.0;
  }
  return l;
}

std::string unscaled_muscles_warning(const Model& model) {
  const std::vector<double> l = normalized_fiber_lengths_at_default_pose(model);
  int beyond = 0;
  std::size_t worst = 0;
  for (std::size_t m = 0; m < l.size(); ++m) {
    beyond += l[m] > 1.3;
    if (l[m] > l[worst]) worst = m;
  }
  if (beyond < 5) return {};
  char buf[300];
  std::snprintf(buf, sizeof buf,
                "%d muscles sit beyond 1.3 optimal fibre lengths at the default pose (%s: %.2f), where their passive forces "
                "are large: were their fibre and tendon lengths scaled with the bones? (--scale-muscles-from GENERIC.osim)",
                beyond, model.muscles[worst].name.c_str(), l[worst]);
  return buf;
}

}  // namespace cpgait
