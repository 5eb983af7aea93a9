#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cpgait/dynamics/contact.h"

namespace cpgait {

FootSphereFit fit_foot_spheres_to_trial(const Model& model, ContactSet& set, const std::vector<double>& time_s,
                                        const Eigen::MatrixXd& q_samples, double max_lift_m) {
  FootSphereFit fit;
  place_ground_under_feet(model, set, time_s, q_samples);
  const std::size_t ns = set.spheres.size();
  const int n = static_cast<int>(q_samples.rows());
  if (ns == 0 || n == 0) return fit;
  // Every sphere's bottom above the ground in every pose.
  const std::vector<Eigen::Vector3d> centre = sphere_centres_over_poses(model, set, q_samples);
  Eigen::MatrixXd h(n, static_cast<Eigen::Index>(ns));
  for (int i = 0; i < n; ++i)
    for (std::size_t s = 0; s < ns; ++s)
      h(i, static_cast<Eigen::Index>(s)) = centre[static_cast<std::size_t>(i) * ns + s].y() - set.spheres[s].radius_m - set.ground_height_m;
  // Each sphere's lowest point brought to the ground. A radius change moves a sphere's bottom by the
  // same amount in every orientation, where a moved centre would tilt with the foot. A sphere that
  // never comes within max_lift_m of the ground (a foot that does not step) is left alone.
  const double low_all = h.minCoeff();
  fit.radius_change_m.assign(ns, 0.0);
  std::vector<bool> fitted(ns, false);
  for (std::size_t s = 0; s < ns; ++s) {
    const auto col = static_cast<Eigen::Index>(s);
    const double low = h.col(col).minCoeff();
    if (low - low_all > max_lift_m) {
      char mm[32];
      std::snprintf(mm, sizeof mm, "%.0f mm", max_lift_m * 1000);
      fit.warnings.push_back("contact sphere " + set.spheres[s].name + " never comes within " + mm + " of the lowest foot in the trial: left as it was");
      continue;
    }
    fit.radius_change_m[s] = low;
    fitted[s] = true;
    h.col(col).array() -= low;
  }
  // One depth for all: the trial's mean vertical ground force over whole strides is body weight,
  // so the spheres, pressed by the recorded poses, should carry it on average. Static force only (the
  // Hunt-Crossley rate term averages out over a stance); monotone in the depth, so bisection.
  const double weight_N = model.total_mass_kg() * model.gravity_m_s2.norm();
  auto mean_force = [&](double depth) {
    double total = 0;
    for (std::size_t s = 0; s < ns; ++s)
      for (int i = 0; i < n; ++i) {
        const double d = depth - h(i, static_cast<Eigen::Index>(s));
        if (d > 0) total += set.spheres[s].stiffness * std::pow(d, 1.5);
      }
    return total / n;
  };
  double lo = 0, hi = 0.05;
  for (int it = 0; it < 60; ++it) (mean_force(0.5 * (lo + hi)) < weight_N ? lo : hi) = 0.5 * (lo + hi);
  fit.depth_m = 0.5 * (lo + hi);
  for (std::size_t s = 0; s < ns; ++s)
    if (fitted[s]) fit.radius_change_m[s] += fit.depth_m;
  for (std::size_t s = 0; s < ns; ++s) {
    set.spheres[s].radius_m += fit.radius_change_m[s];
    if (set.spheres[s].radius_m < 0.005) {
      fit.warnings.push_back("contact sphere " + set.spheres[s].name + " would shrink below 5 mm: kept at 5 mm");
      fit.radius_change_m[s] += 0.005 - set.spheres[s].radius_m;
      set.spheres[s].radius_m = 0.005;
    }
  }
  fit.mean_force_N = mean_force(fit.depth_m);
  return fit;
}

}  // namespace cpgait
