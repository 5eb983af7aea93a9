#include "cpgait/kinematics/gait_events.h"

#include "cpgait/capture/input_error.h"
#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait {

std::vector<double> heel_strikes_zeni(const Model& model, const std::vector<double>& time, const Eigen::MatrixXd& q,
                                      const std::string& foot_body, double min_cycle_s) {
  const int foot = model.body_index(foot_body);
  if (foot < 0) throw InputError(model.source, 0, "foot_body", "the model has no body " + foot_body);
  const int pelvis = model.joints.front().child_body;  // the root segment
  const Eigen::Index F = q.rows();
  if (F < 3) return {};
  KinematicsWorkspace<double> ws(model);
  std::vector<Eigen::Vector3d> foot_p(static_cast<std::size_t>(F)), pelvis_p(static_cast<std::size_t>(F));
  // Progression: where the pelvis faces (its x axis, anterior by OpenSim's convention), averaged and
  // made horizontal. Not the pelvis' displacement: on a treadmill (as OpenSim's subject01) it barely moves.
  Eigen::Vector3d forward = Eigen::Vector3d::Zero();
  for (Eigen::Index f = 0; f < F; ++f) {
    const Eigen::VectorXd qf = q.row(f).transpose();
    forward_kinematics(model, qf.data(), ws);
    foot_p[static_cast<std::size_t>(f)] = ws.body_in_ground[static_cast<std::size_t>(foot)].translation_m;
    pelvis_p[static_cast<std::size_t>(f)] = ws.body_in_ground[static_cast<std::size_t>(pelvis)].translation_m;
    forward += ws.body_in_ground[static_cast<std::size_t>(pelvis)].rotation.col(0);
  }
  const Eigen::Vector3d up = -model.gravity_m_s2.normalized();
  forward -= forward.dot(up) * up;
  if (forward.norm() < 1e-9) return {};
  forward.normalize();
  std::vector<double> d(static_cast<std::size_t>(F));
  for (std::size_t f = 0; f < d.size(); ++f) d[f] = (foot_p[f] - pelvis_p[f]).dot(forward);
  std::vector<double> strikes;
  for (std::size_t f = 1; f + 1 < d.size(); ++f) {
    if (!(d[f] >= d[f - 1] && d[f] > d[f + 1])) continue;
    // Sub-frame peak: vertex of the parabola through the three samples (uniform spacing assumed locally).
    const double denom = d[f - 1] - 2 * d[f] + d[f + 1];
    const double offset = denom < 0 ? 0.5 * (d[f - 1] - d[f + 1]) / denom : 0.0;
    const double h = 0.5 * (time[f + 1] - time[f - 1]);
    const double t = time[f] + offset * h;
    if (!strikes.empty() && t - strikes.back() < min_cycle_s) {
      continue;  // a wobble within the same stance
    }
    strikes.push_back(t);
  }
  return strikes;
}

}  // namespace cpgait
