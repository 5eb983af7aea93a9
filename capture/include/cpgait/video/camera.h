#pragma once
// Calibrated cameras: OpenCV's pinhole model with radial-tangential distortion (k1 k2 p1 p2 k3) and
// OpenCV's pixel convention (the centre of pixel (i, j) is at (i, j)). Extrinsics map the lab (world)
// frame into the camera frame: x_cam = R * x_world + t, z along the optical axis, y down.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

namespace cpgait::video {

struct Camera {
  std::string name;
  int width_px = 0;
  int height_px = 0;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  std::array<double, 5> distortion{};  // k1 k2 p1 p2 k3
  Eigen::Matrix3d rotation_cam_from_world = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation_cam_from_world_m = Eigen::Vector3d::Zero();
  // Camera clock minus the reference clock: camera frame i was exposed at i / fps - time_offset_s.
  double time_offset_s = 0;

  Eigen::Matrix3d camera_matrix() const;
  Eigen::Vector3d position_world_m() const { return -rotation_cam_from_world.transpose() * translation_cam_from_world_m; }
};

using CameraRig = std::vector<Camera>;

// Projection of a point in the camera frame (z > 0) through distortion to pixels; `intrinsics` is
// {fx, fy, cx, cy, k1, k2, p1, p2, k3}. Templated so Ceres differentiates it.
template <typename T>
Eigen::Matrix<T, 2, 1> project_camera_point(const T* intrinsics, const Eigen::Matrix<T, 3, 1>& p_cam) {
  const T x = p_cam.x() / p_cam.z(), y = p_cam.y() / p_cam.z();
  const T r2 = x * x + y * y;
  const T k1 = intrinsics[4], k2 = intrinsics[5], p1 = intrinsics[6], p2 = intrinsics[7], k3 = intrinsics[8];
  const T radial = T(1) + r2 * (k1 + r2 * (k2 + r2 * k3));
  const T xd = x * radial + T(2) * p1 * x * y + p2 * (r2 + T(2) * x * x);
  const T yd = y * radial + p1 * (r2 + T(2) * y * y) + T(2) * p2 * x * y;
  return {intrinsics[0] * xd + intrinsics[2], intrinsics[1] * yd + intrinsics[3]};
}

std::array<double, 9> intrinsics_of(const Camera& camera);

// Pixel of a lab point; NaN when the point is not in front of the camera.
Eigen::Vector2d project(const Camera& camera, const Eigen::Vector3d& p_world_m);

// Normalized image coordinates (x/z, y/z in the camera frame) of a distorted pixel: the inverse of
// the distortion by fixed-point iteration, as cv::undistortPoints does.
Eigen::Vector2d undistort_to_normalized(const Camera& camera, const Eigen::Vector2d& pixel);

// Calibration files: our JSON ("cpgait.calibration/1", see write_calibration) or OpenCV FileStorage
// YAML/XML (one camera's calibrateCamera output, or `cameras:` holding several). Throws InputError.
CameraRig read_calibration(const std::string& path);
CameraRig parse_calibration_json(const std::string& text, const std::string& name);
void write_calibration(const CameraRig& rig, const std::string& path);
std::string format_calibration_json(const CameraRig& rig);

}  // namespace cpgait::video
