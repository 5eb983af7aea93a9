// OpenCV FileStorage calibrations (.yml/.yaml/.xml): one camera map, or a "cameras" sequence of them.
#include <opencv2/core.hpp>

#include "cpgait/capture/input_error.h"
#include "cpgait/video/footage.h"

namespace cpgait::video {
namespace {

Eigen::MatrixXd opencv_matrix(const cv::FileNode& n, const std::string& name, const std::string& field, int rows, int cols) {
  cv::Mat m;
  n >> m;
  if (m.empty()) throw InputError(name, 0, field, "missing");
  m.convertTo(m, CV_64F);
  if (static_cast<int>(m.total()) != rows * cols)
    throw InputError(name, 0, field, "expected " + std::to_string(rows) + "x" + std::to_string(cols) + " values");
  Eigen::MatrixXd out(rows, cols);
  for (int i = 0; i < rows * cols; ++i) out(i / cols, i % cols) = m.at<double>(i);
  return out;
}

Camera camera_from_opencv(const cv::FileNode& n, const std::string& name, const std::string& at) {
  Camera c;
  c.name = n["name"].empty() ? at : static_cast<std::string>(n["name"]);
  c.width_px = static_cast<int>(n["image_width"]);
  c.height_px = static_cast<int>(n["image_height"]);
  if (c.width_px <= 0 || c.height_px <= 0) throw InputError(name, 0, at + ".image_width", "missing or not positive");
  const Eigen::MatrixXd K = opencv_matrix(n["camera_matrix"], name, at + ".camera_matrix", 3, 3);
  c.fx_px = K(0, 0);
  c.fy_px = K(1, 1);
  c.cx_px = K(0, 2);
  c.cy_px = K(1, 2);
  cv::Mat d;
  n["distortion_coefficients"] >> d;
  d.convertTo(d, CV_64F);
  if (d.total() > 5 && d.total() != 0) {
    for (std::size_t i = 5; i < d.total(); ++i)
      if (d.at<double>(static_cast<int>(i)) != 0)
        throw InputError(name, 0, at + ".distortion_coefficients", "only k1 k2 p1 p2 k3 are supported");
  }
  for (std::size_t i = 0; i < std::min<std::size_t>(5, d.total()); ++i) c.distortion[i] = d.at<double>(static_cast<int>(i));
  if (!n["rotation_matrix"].empty()) {
    c.rotation_cam_from_world = opencv_matrix(n["rotation_matrix"], name, at + ".rotation_matrix", 3, 3);
  } else if (!n["rvec"].empty()) {
    const Eigen::Vector3d v = opencv_matrix(n["rvec"], name, at + ".rvec", 3, 1);
    if (v.norm() > 0) c.rotation_cam_from_world = Eigen::AngleAxisd(v.norm(), v.normalized()).toRotationMatrix();
  }
  if (!n["tvec"].empty()) c.translation_cam_from_world_m = opencv_matrix(n["tvec"], name, at + ".tvec", 3, 1);
  if (!n["time_offset_s"].empty()) c.time_offset_s = static_cast<double>(n["time_offset_s"]);
  return c;
}

}  // namespace

CameraRig read_opencv_calibration(const std::string& path) {
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) throw InputError(path, 0, "", "not an OpenCV FileStorage (YAML/XML) file");
    CameraRig rig;
    const cv::FileNode cams = fs["cameras"];
    if (!cams.empty()) {
      if (!cams.isSeq()) throw InputError(path, 0, "cameras", "expected a sequence of camera maps");
      int i = 0;
      for (const auto& n : cams) rig.push_back(camera_from_opencv(n, path, "cameras[" + std::to_string(i++) + "]"));
    } else {
      rig.push_back(camera_from_opencv(fs.root(), path, "camera"));
    }
    return rig;
  } catch (const cv::Exception& e) {
    throw InputError(path, 0, "", std::string("unreadable OpenCV calibration: ") + e.what());
  }
}

}  // namespace cpgait::video
