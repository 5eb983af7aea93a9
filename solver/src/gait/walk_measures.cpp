#include "cpgait/gait/walk_measures.h"

#include <algorithm>
#include <cmath>

namespace cpgait {

ContactPhases contact_phases(const std::vector<double>& time_s, const std::vector<double>& load_r, const std::vector<double>& load_l,
                             double t0, double t1) {
  ContactPhases p;
  int n = 0, loaded[2] = {0, 0}, both = 0, neither = 0;
  for (std::size_t i = 0; i < time_s.size(); ++i) {
    if (time_s[i] < t0 - 1e-9 || time_s[i] >= t1 - 1e-9) continue;
    const bool r = load_r[i] > kFootContactThresholdN, l = load_l[i] > kFootContactThresholdN;
    ++n, loaded[0] += r, loaded[1] += l, both += r && l, neither += !r && !l;
  }
  if (n == 0) return p;
  p.stance_percent[0] = 100.0 * loaded[0] / n, p.stance_percent[1] = 100.0 * loaded[1] / n;
  p.double_support_percent = 100.0 * both / n;
  p.flight_percent = 100.0 * neither / n;
  return p;
}

std::vector<double> rising_through(const std::vector<double>& t, const std::vector<double>& v, double threshold, double min_gap_s,
                                   double hold_s) {
  std::vector<double> out;
  for (std::size_t i = 1; i < v.size(); ++i)
    if (v[i - 1] < threshold && v[i] >= threshold) {
      const double tc = t[i - 1] + (threshold - v[i - 1]) / (v[i] - v[i - 1]) * (t[i] - t[i - 1]);
      std::size_t j = i;
      while (j < v.size() && v[j] >= threshold && t[j] - tc < hold_s) ++j;
      const bool held = j == v.size() || v[j] >= threshold;
      if (held && (out.empty() || tc - out.back() >= min_gap_s)) out.push_back(tc);
    }
  return out;
}

bool inside_convex_hull(std::vector<Eigen::Vector2d> pts, const Eigen::Vector2d& p) {
  if (pts.size() < 3) return false;
  std::sort(pts.begin(), pts.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Eigen::Vector2d> hull(2 * pts.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k - 1);
  if (hull.size() < 3) return false;
  for (std::size_t i = 0; i < hull.size(); ++i)
    if (cross(hull[i], hull[(i + 1) % hull.size()], p) < 0) return false;
  return true;
}

bool centre_of_mass_supported(const Model& model, const KinematicsWorkspace<double>& kin, const std::vector<Eigen::Vector3d>& contact_force_N,
                              const std::vector<Eigen::Vector3d>& contact_point_m, bool planar) {
  const Eigen::Vector3d com = centre_of_mass_m(model, kin);
  std::vector<Eigen::Vector2d> support;
  for (std::size_t sp = 0; sp < contact_force_N.size(); ++sp)
    if (contact_force_N[sp].y() > kFootContactThresholdN) support.emplace_back(contact_point_m[sp].x(), contact_point_m[sp].z());
  if (!planar) return inside_convex_hull(support, Eigen::Vector2d(com.x(), com.z()));
  bool over = false;
  for (const auto& a : support)
    for (const auto& b : support) over = over || (a.x() <= com.x() && com.x() <= b.x());
  return over;
}

void measure_walk(const Model& model, const WalkRecord& w, ReproducedGaitResult& r) {
  const int nq = model.num_coordinates(), ns = static_cast<int>(r.time_s.size());
  // RMS against the reference up to `until` s (and the reference's end).
  auto tracking_rms_until = [&](double until) {
    Eigen::VectorXd rms = Eigen::VectorXd::Zero(nq);
    int n = 0;
    for (int i = 0; i < ns; ++i)
      if (r.time_s[i] <= std::min(until, w.tracked_until_s) + 1e-9) rms += (r.q.row(i) - r.q_reference.row(i)).transpose().cwiseAbs2(), ++n;
    return Eigen::VectorXd((rms / std::max(1, n)).cwiseSqrt());
  };
  r.tracking_rms = tracking_rms_until(w.tracked_until_s);
  r.tracking_rms_first_two_cycles = tracking_rms_until(2 * w.cycle_s / w.speed);
  for (int c = 0; c < nq; ++c)
    if (model.coordinates[c].is_angle() && r.tracking_rms[c] > r.worst_rotation_rms_rad) {
      r.worst_rotation_rms_rad = r.tracking_rms[c];
      r.worst_rotation = model.coordinates[c].name;
    }
  // Heel strikes: a foot's spheres pressing through the threshold and bearing load for a fifth of a
  // cycle, at least 0.4 s apart. Without the hold, toes touching down for 40-80 ms just after toe-off
  // counted as strikes and halved subject01's stride - measured.
  std::vector<double> load[2];
  for (int i = 0; i < ns; ++i) {
    double side_load[2] = {0, 0};
    for (std::size_t s = 0; s < w.sphere_side->size(); ++s) {
      const int side = (*w.sphere_side)[s];
      if (side >= 0) side_load[side] += r.contact_force_N(i, 3 * s + 1);
    }
    load[0].push_back(side_load[0]);
    load[1].push_back(side_load[1]);
  }
  const double stance_hold_s = 0.2 * w.cycle_s / w.speed;
  r.heel_strikes_r_s = rising_through(r.time_s, load[0], kFootContactThresholdN, 0.4, stance_hold_s);
  r.heel_strikes_l_s = rising_through(r.time_s, load[1], kFootContactThresholdN, 0.4, stance_hold_s);
  // Strides of the right foot (the CPG's cycle): time, and the pelvis' horizontal travel.
  const int tx = model.coordinate_index("pelvis_tx"), tz = model.coordinate_index("pelvis_tz");
  auto pelvis_xz = [&](double t) {
    const int i = std::clamp(static_cast<int>(std::lround(t / w.dt_s)), 0, ns - 1);
    return Eigen::Vector2d(tx >= 0 ? r.q(i, tx) : 0.0, tz >= 0 ? r.q(i, tz) : 0.0);
  };
  const auto& hs = r.heel_strikes_r_s;
  // On a treadmill the distance walked is the belt's travel plus the pelvis' drift over it.
  const Eigen::Vector2d belt(w.belt_velocity_m_s.x(), w.belt_velocity_m_s.z());
  auto walked = [&](double t0, double t1) { return (pelvis_xz(t1) - pelvis_xz(t0) - belt * (t1 - t0)).norm(); };
  if (hs.size() >= 2) {
    r.stride_time_s = (hs.back() - hs.front()) / (hs.size() - 1);
    r.stride_length_m = walked(hs.front(), hs.back()) / (hs.size() - 1);
    r.speed_m_s = r.stride_length_m / r.stride_time_s;
  }
  if (ns > 1) r.distance_m = walked(0, r.time_s.back());
  if (r.frozen_at_s < 0) {  // a walk that stopped has no direction to keep, and its belt slowed
    r.drift_rad = walk_drift_rad(r.time_s, r.q, model.coordinate_index("pelvis_rotation"), tx, tz, belt, w.cycle_s / w.speed);
    r.cycle_change_rad = walk_cycle_change_rad(r.time_s, r.q, walk_angles(model), w.cycle_s / w.speed);
  }
  if (hs.size() >= 2) {
    const ContactPhases p = contact_phases(r.time_s, load[0], load[1], hs.front(), hs.back());
    r.stance_percent_r = p.stance_percent[0], r.stance_percent_l = p.stance_percent[1], r.double_support_percent = p.double_support_percent;
    r.flight_percent = p.flight_percent;
  }
  // The stand: the longest stretch after the freeze with the pelvis at rest (under 0.1 m/s over the
  // ground) and the centre of mass over the feet; it begins when the model came to rest.
  if (r.frozen_at_s >= 0 && r.fell_at_s < 0) {
    const std::vector<double>& pelvis_speed = *w.pelvis_speed_m_s;
    std::size_t begin = 0;
    bool standing = false;
    for (std::size_t i = 0; i <= pelvis_speed.size(); ++i) {
      const bool now = i < pelvis_speed.size() && r.time_s[i] >= r.frozen_at_s && pelvis_speed[i] < 0.1 && (*w.com_supported)[i];
      if (now && !standing) begin = i;
      if (!now && standing && r.time_s[i - 1] - r.time_s[begin] >= r.stood_s) {
        r.stopped_at_s = r.time_s[begin];
        r.stood_s = r.time_s[i - 1] - r.time_s[begin];
      }
      standing = now;
    }
  }
  if (w.residuals && ns > 0) {
    const std::vector<int>& root = *w.root;
    double force = 0, moment = 0;
    for (int i = 0; i < ns; ++i) {
      Eigen::Vector3d F = Eigen::Vector3d::Zero(), M = Eigen::Vector3d::Zero();
      int nf = 0, nmnt = 0;
      for (std::size_t j = 0; j < root.size(); ++j)
        if (model.coordinates[root[j]].is_angle()) M[nmnt++ % 3] = r.residuals(i, j);
        else F[nf++ % 3] = r.residuals(i, j);
      force += F.norm();
      moment += M.norm();
    }
    r.mean_residual_force_percent_bw = 100 * force / ns / (model.total_mass_kg() * model.gravity_m_s2.norm());
    r.mean_residual_moment_Nm = moment / ns;
  }
}

std::vector<int> walk_angles(const Model& model) {
  std::vector<int> angles;
  for (int c = 0; c < model.num_coordinates(); ++c)
    if (model.coordinates[c].is_angle()) angles.push_back(c);
  return angles;
}

double walk_cycle_change_rad(const std::vector<double>& time_s, const Eigen::MatrixXd& q, const std::vector<int>& angles, double cycle_s) {
  const Eigen::Index ns = static_cast<Eigen::Index>(time_s.size());
  if (ns < 3 || angles.empty() || !(cycle_s > 0)) return 0;
  const double dt = (time_s.back() - time_s.front()) / static_cast<double>(ns - 1);
  const Eigen::Index lag = static_cast<Eigen::Index>(std::lround(cycle_s / dt));
  if (lag < 1 || 2 * lag >= ns) return 0;
  double sum = 0;
  for (Eigen::Index i = ns - lag; i < ns; ++i)
    for (int c : angles) sum += (q(i, c) - q(i - lag, c)) * (q(i, c) - q(i - lag, c));
  return std::sqrt(sum / static_cast<double>(lag * static_cast<Eigen::Index>(angles.size())));
}

double walk_drift_rad(const std::vector<double>& time_s, const Eigen::MatrixXd& q, int yaw, int tx, int tz, const Eigen::Vector2d& belt_xz_m_s,
                      double cycle_s) {
  const int ns = static_cast<int>(time_s.size());
  if (ns < 2 || tx < 0 || tz < 0 || !(cycle_s > 0) || time_s.back() / 2 < cycle_s) return 0;
  // The direction of travel over the belt and the mean yaw over the cycle ending at t1.
  auto direction_and_yaw = [&](double t1) {
    const double t0 = t1 - cycle_s;
    auto at = [&](double t) {
      const auto i = static_cast<Eigen::Index>(std::lower_bound(time_s.begin(), time_s.end(), t - 1e-9) - time_s.begin());
      return std::min<Eigen::Index>(i, ns - 1);
    };
    const Eigen::Index i0 = at(t0), i1 = at(t1);
    const Eigen::Vector2d d = Eigen::Vector2d(q(i1, tx) - q(i0, tx), q(i1, tz) - q(i0, tz)) - belt_xz_m_s * (time_s[i1] - time_s[i0]);
    const double mean_yaw = yaw >= 0 ? q.col(yaw).segment(i0, i1 - i0 + 1).mean() : 0.0;
    return Eigen::Vector2d(std::atan2(-d.y(), d.x()), mean_yaw);
  };
  Eigen::Vector2d change = direction_and_yaw(time_s.back()) - direction_and_yaw(time_s.back() / 2);
  change[0] = std::remainder(change[0], 2 * M_PI);  // a turn through the direction's branch cut
  return change.cwiseAbs().sum();
}

}  // namespace cpgait
