#pragma once
// A tag's pose from one camera by IPPE (infinitesimal plane-based pose estimation, OpenCV's
// SOLVEPNP_IPPE_SQUARE): the fallback when only one camera sees a tag. Depth is far less certain than
// from triangulation, so corners placed this way are flagged as single-view.
#include <Eigen/Geometry>

#include "cpgait/video/camera.h"
#include "cpgait/video/tag_detector.h"

namespace cpgait::video {

struct TagPose {
  Eigen::Matrix3d rotation_cam_from_tag = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation_cam_from_tag_m = Eigen::Vector3d::Zero();
  double rms_reprojection_px = 0;
  // Reprojection error of IPPE's second pose over the first's: near 1, the tag's tilt is ambiguous.
  double ambiguity = 0;
};

TagPose tag_pose_ippe(const Camera& camera, const TagDetection& detection, double tag_size_m);

}  // namespace cpgait::video
