#include "cpgait/video/camera.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/video/footage.h"

namespace cpgait::video {

Eigen::Matrix3d Camera::camera_matrix() const {
  Eigen::Matrix3d K;
  K << fx_px, 0, cx_px, 0, fy_px, cy_px, 0, 0, 1;
  return K;
}

std::array<double, 9> intrinsics_of(const Camera& c) {
  return {c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.distortion[0], c.distortion[1], c.distortion[2], c.distortion[3],
          c.distortion[4]};
}

Eigen::Vector2d project(const Camera& camera, const Eigen::Vector3d& p_world_m) {
  const Eigen::Vector3d p_cam = camera.rotation_cam_from_world * p_world_m + camera.translation_cam_from_world_m;
  if (!(p_cam.z() > 1e-9)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  const auto k = intrinsics_of(camera);
  return project_camera_point(k.data(), p_cam);
}

Eigen::Vector2d undistort_to_normalized(const Camera& c, const Eigen::Vector2d& pixel) {
  const double xd = (pixel.x() - c.cx_px) / c.fx_px, yd = (pixel.y() - c.cy_px) / c.fy_px;
  const auto& d = c.distortion;
  double x = xd, y = yd;
  // Fixed-point iteration x = (xd - tangential(x)) / radial(x); converges for the distortions of
  // real lenses inside the image (OpenCV iterates the same way).
  for (int it = 0; it < 20; ++it) {
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
    const double dx = 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
    const double dy = d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
    const double nx = (xd - dx) / radial, ny = (yd - dy) / radial;
    const bool done = std::abs(nx - x) + std::abs(ny - y) < 1e-14;
    x = nx;
    y = ny;
    if (done) break;
  }
  return {x, y};
}

namespace {

using nlohmann::json;

Camera camera_from_json(const json& j, const std::string& name, const std::string& at) {
  Camera c;
  c.name = json_field_or(j, "name", at, name, at);
  c.width_px = json_field<int>(j, "width", name, at);
  c.height_px = json_field<int>(j, "height", name, at);
  c.fx_px = json_field<double>(j, "fx", name, at);
  c.fy_px = json_field<double>(j, "fy", name, at);
  c.cx_px = json_field<double>(j, "cx", name, at);
  c.cy_px = json_field<double>(j, "cy", name, at);
  if (c.width_px <= 0 || c.height_px <= 0) throw InputError(name, 0, at + ".width", "image size must be positive");
  if (!(c.fx_px > 0) || !(c.fy_px > 0)) throw InputError(name, 0, at + ".fx", "focal lengths must be positive pixels");
  if (j.contains("distortion")) {
    const auto d = json_field<std::vector<double>>(j, "distortion", name, at);
    if (d.size() > 5 || d.size() < 4)
      throw InputError(name, 0, at + ".distortion", "expected 4 or 5 coefficients k1 k2 p1 p2 [k3]");
    for (std::size_t i = 0; i < d.size(); ++i) c.distortion[i] = d[i];
  }
  if (j.contains("rotation_cam_from_world")) {
    const auto r = json_field<std::vector<double>>(j, "rotation_cam_from_world", name, at);
    if (r.size() != 9) throw InputError(name, 0, at + ".rotation_cam_from_world", "expected 9 numbers, row-major");
    for (int i = 0; i < 9; ++i) c.rotation_cam_from_world(i / 3, i % 3) = r[static_cast<std::size_t>(i)];
    const double orth = (c.rotation_cam_from_world * c.rotation_cam_from_world.transpose() - Eigen::Matrix3d::Identity()).norm();
    if (orth > 1e-6 || c.rotation_cam_from_world.determinant() < 0)
      throw InputError(name, 0, at + ".rotation_cam_from_world", "not a rotation matrix");
  } else if (j.contains("rvec")) {
    const auto r = json_field<std::vector<double>>(j, "rvec", name, at);
    if (r.size() != 3) throw InputError(name, 0, at + ".rvec", "expected a Rodrigues vector of 3 numbers");
    const Eigen::Vector3d v(r[0], r[1], r[2]);
    c.rotation_cam_from_world = v.norm() > 0 ? Eigen::AngleAxisd(v.norm(), v.normalized()).toRotationMatrix()
                                             : Eigen::Matrix3d::Identity();
  }
  if (j.contains("translation_cam_from_world_m")) {
    const auto t = json_field<std::vector<double>>(j, "translation_cam_from_world_m", name, at);
    if (t.size() != 3) throw InputError(name, 0, at + ".translation_cam_from_world_m", "expected 3 numbers");
    c.translation_cam_from_world_m = Eigen::Vector3d(t[0], t[1], t[2]);
  }
  c.time_offset_s = json_field_or(j, "time_offset_s", 0.0, name, at);
  return c;
}

}  // namespace

CameraRig parse_calibration_json(const std::string& text, const std::string& name) {
  const json j = parse_json_input(text, name);
  if (!j.is_object() || !j.contains("cameras") || !j["cameras"].is_array() || j["cameras"].empty())
    throw InputError(name, 0, "cameras", "expected an object with a non-empty \"cameras\" array");
  CameraRig rig;
  for (std::size_t i = 0; i < j["cameras"].size(); ++i)
    rig.push_back(camera_from_json(j["cameras"][i], name, "cameras[" + std::to_string(i) + "]"));
  for (std::size_t a = 0; a < rig.size(); ++a)
    for (std::size_t b = a + 1; b < rig.size(); ++b)
      if (rig[a].name == rig[b].name)
        throw InputError(name, 0, "cameras[" + std::to_string(b) + "].name", "duplicate camera name " + rig[b].name);
  return rig;
}

CameraRig read_calibration(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".yml" || ext == ".yaml" || ext == ".xml") {
    if (!std::filesystem::exists(path)) throw InputError(path, 0, "", "file not found");
    return footage().read_opencv_calibration(path);
  }
  return parse_calibration_json(text::read_file(path), path);
}

std::string format_calibration_json(const CameraRig& rig) {
  json cams = json::array();
  for (const Camera& c : rig) {
    std::vector<double> r(9);
    for (int i = 0; i < 9; ++i) r[static_cast<std::size_t>(i)] = c.rotation_cam_from_world(i / 3, i % 3);
    cams.push_back({{"name", c.name},
                    {"width", c.width_px},
                    {"height", c.height_px},
                    {"fx", c.fx_px},
                    {"fy", c.fy_px},
                    {"cx", c.cx_px},
                    {"cy", c.cy_px},
                    {"distortion", std::vector<double>(c.distortion.begin(), c.distortion.end())},
                    {"rotation_cam_from_world", r},
                    {"translation_cam_from_world_m", {c.translation_cam_from_world_m.x(), c.translation_cam_from_world_m.y(),
                                                      c.translation_cam_from_world_m.z()}},
                    {"time_offset_s", c.time_offset_s}});
  }
  return json{{"schema", "cpgait.calibration/1"}, {"cameras", cams}}.dump(2) + "\n";
}

void write_calibration(const CameraRig& rig, const std::string& path) {
  std::ofstream out(path);
  out << format_calibration_json(rig);
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace cpgait::video
