#include "cpgait/video/tag_pose.h"

#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "cpgait/video/tag_set.h"

namespace cpgait::video {

TagPose tag_pose_ippe(const Camera& camera, const TagDetection& detection, double tag_size_m) {
  // IPPE_SQUARE wants the corners in exactly AprilTag's order: (-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2).
  const auto corners = tag_corners_in_tag_frame(tag_size_m);
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (int k = 0; k < 4; ++k) {
    const auto& c = corners[static_cast<std::size_t>(k)];
    object.emplace_back(c.x(), c.y(), c.z());
    image.emplace_back(detection.corners_px[static_cast<std::size_t>(k)].x(), detection.corners_px[static_cast<std::size_t>(k)].y());
  }
  const Eigen::Matrix3d K = camera.camera_matrix();
  const cv::Mat Kcv = (cv::Mat_<double>(3, 3) << K(0, 0), 0, K(0, 2), 0, K(1, 1), K(1, 2), 0, 0, 1);
  const cv::Mat dist(1, 5, CV_64F, const_cast<double*>(camera.distortion.data()));
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat errors;
  const int n = cv::solvePnPGeneric(object, image, Kcv, dist, rvecs, tvecs, false, cv::SOLVEPNP_IPPE_SQUARE, cv::noArray(),
                                    cv::noArray(), errors);
  TagPose pose;
  if (n < 1) {
    pose.rms_reprojection_px = std::numeric_limits<double>::infinity();
    return pose;
  }
  // IPPE returns the two poses a plane's image allows, best first. When the second explains the
  // corners almost as well (small or distant tags), the tilt is a coin toss: report the ratio.
  pose.ambiguity = n > 1 ? errors.at<double>(1) / std::max(errors.at<double>(0), 1e-9) : 1e9;
  const cv::Mat& rvec = rvecs[0];
  const cv::Mat& tvec = tvecs[0];
  const Eigen::Vector3d r(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  pose.rotation_cam_from_tag = r.norm() > 0 ? Eigen::AngleAxisd(r.norm(), r.normalized()).toRotationMatrix()
                                            : Eigen::Matrix3d::Identity();
  pose.translation_cam_from_tag_m = {tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)};
  const auto k = intrinsics_of(camera);
  double sum2 = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d p = pose.rotation_cam_from_tag * corners[static_cast<std::size_t>(i)] + pose.translation_cam_from_tag_m;
    sum2 += (project_camera_point(k.data(), p) - detection.corners_px[static_cast<std::size_t>(i)]).squaredNorm();
  }
  pose.rms_reprojection_px = std::sqrt(sum2 / 4);
  return pose;
}

}  // namespace cpgait::video
