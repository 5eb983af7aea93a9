#include "cpgait/video/register_tags.h"

#include <Eigen/SVD>
#include <cmath>
#include <sstream>

#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait::video {

std::string TagRegistrationSummary::BriefReport() const {
  std::ostringstream s;
  double max_shift = 0, max_turn = 0;
  for (double d : shift_m) max_shift = std::max(max_shift, d);
  for (double d : turn_rad) max_turn = std::max(max_turn, d);
  s << "tag registration: " << moved.size() << " tags re-placed (largest shift " << 1000 * max_shift << " mm, turn "
    << max_turn * 180 / M_PI << " deg), " << unchanged.size() << " kept; static-trial marker RMS " << 1000 * marker_rms_before_m
    << " mm -> " << 1000 * marker_rms_after_m << " mm";
  return s.str();
}

namespace {

// Rotation R and translation p minimising sum |R a_k + p - b_k|^2 (Kabsch, with the reflection fix).
void kabsch(const std::array<Eigen::Vector3d, 4>& a, const std::array<Eigen::Vector3d, 4>& b, Eigen::Matrix3d& R, Eigen::Vector3d& p) {
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  for (int k = 0; k < 4; ++k) ca += a[static_cast<std::size_t>(k)] / 4, cb += b[static_cast<std::size_t>(k)] / 4;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 4; ++k) H += (a[static_cast<std::size_t>(k)] - ca) * (b[static_cast<std::size_t>(k)] - cb).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  R = svd.matrixV() * D * svd.matrixU().transpose();
  p = cb - R * ca;
}

}  // namespace

TagSet register_tag_set(const Model& model, const TagSet& approximate, const MarkerTrial& markers,
                        const TagRegistrationOptions& options, TagRegistrationSummary* summary) {
  const Model with_tags = with_tag_markers(model, approximate);
  const IkResult ik = inverse_kinematics(with_tags, markers, IkTaskSet{});
  TagRegistrationSummary s;
  s.marker_rms_before_m = ik.summary.mean_marker_rms_m;
  TagSet out = approximate;
  KinematicsWorkspace<double> ws(with_tags);
  for (TagMount& tag : out.tags) {
    const int body = model.body_index(tag.body);
    std::array<Eigen::Vector3d, 4> mean_in_body{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    std::array<int, 4> columns{};
    for (int k = 0; k < 4; ++k) columns[static_cast<std::size_t>(k)] = markers.marker_index(tag.corner_markers[static_cast<std::size_t>(k)]);
    int frames = 0;
    for (int i = 0; i < ik.summary.frames; ++i) {
      const int f = i;  // IK ran on every frame of the static trial
      bool all = true;
      for (int k = 0; k < 4; ++k) all = all && columns[static_cast<std::size_t>(k)] >= 0 && !std::isnan(markers.position_m(f, columns[static_cast<std::size_t>(k)])[0]);
      if (!all) continue;
      const Eigen::VectorXd q = ik.q.row(i).transpose();
      forward_kinematics(with_tags, q.data(), ws);
      const auto& X = ws.body_in_ground[static_cast<std::size_t>(body)];
      for (int k = 0; k < 4; ++k)
        mean_in_body[static_cast<std::size_t>(k)] += X.rotation.transpose() * (markers.position_m(f, columns[static_cast<std::size_t>(k)]) - X.translation_m);
      ++frames;
    }
    if (frames < options.min_frames) {
      s.unchanged.push_back(tag.id);
      continue;
    }
    for (auto& p : mean_in_body) p /= frames;
    Eigen::Matrix3d R;
    Eigen::Vector3d p;
    kabsch(tag_corners_in_tag_frame(tag.size_m), mean_in_body, R, p);
    s.moved.push_back(tag.id);
    s.shift_m.push_back((p - tag.position_in_body_m).norm());
    s.turn_rad.push_back(Eigen::AngleAxisd(tag.rotation_body_from_tag.transpose() * R).angle());
    tag.rotation_body_from_tag = R;
    tag.position_in_body_m = p;
  }
  s.marker_rms_after_m = inverse_kinematics(with_tag_markers(model, out), markers, IkTaskSet{}).summary.mean_marker_rms_m;
  if (summary) *summary = s;
  return out;
}

}  // namespace cpgait::video
