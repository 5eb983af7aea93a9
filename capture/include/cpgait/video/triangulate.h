#pragma once
// A 3-D point from its pixels in several calibrated cameras: linear triangulation (DLT on undistorted
// normalized coordinates) for a start, then Ceres minimises the pixel reprojection error through the
// full distortion model. Views whose error stays above the threshold are dropped, worst first, so
// a mis-detected or occluded corner in one camera does not pull the point.
#include <Eigen/Core>
#include <vector>

#include "cpgait/video/camera.h"

namespace cpgait::video {

struct PixelObservation {
  int camera = 0;  // index into the rig
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct TriangulationOptions {
  double max_reprojection_error_px = 2.0;  // per view, after refinement
  int min_views = 2;
  bool refine = true;  // Ceres refinement after DLT (off: DLT only)
};

struct TriangulatedPoint {
  Eigen::Vector3d position_m = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double rms_reprojection_px = std::numeric_limits<double>::quiet_NaN();
  int views_used = 0;
  std::vector<int> rejected_cameras;
  bool valid() const { return views_used > 0; }
};

// Homogeneous DLT on normalized coordinates; `normalized[i]` belongs to camera `cameras[i]`.
Eigen::Vector3d triangulate_dlt(const CameraRig& rig, const std::vector<int>& cameras,
                                const std::vector<Eigen::Vector2d>& normalized);

TriangulatedPoint triangulate_point(const CameraRig& rig, const std::vector<PixelObservation>& observations,
                                    const TriangulationOptions& options = {});

}  // namespace cpgait::video
