// What capture and calibration take and give, without OpenCV: the video arguments, the reports and
// the quality table (the command line and the service use these without loading the footage module).
#include <filesystem>
#include <sstream>

#include "cpgait/capture/input_error.h"
#include "cpgait/video/calibrate_cameras.h"
#include "cpgait/video/capture_markers.h"

namespace cpgait::video {

std::string CaptureSummary::BriefReport() const {
  std::ostringstream s;
  s << "capture: " << num_frames << " frames from " << cameras.size() << " cameras; corners triangulated "
    << corners_triangulated << ", single-view " << corners_single_view << ", gap-filled " << corners_filled
    << ", missing " << corners_missing
    << "; views rejected " << views_rejected << "; median reprojection " << median_reprojection_px << " px; detect "
    << detect_seconds << " s, triangulate " << triangulate_seconds << " s";
  return s.str();
}

std::pair<std::string, std::string> parse_video_argument(const std::string& argument) {
  const auto eq = argument.find('=');
  if (eq != std::string::npos) return {argument.substr(0, eq), argument.substr(eq + 1)};
  return {std::filesystem::path(argument).stem().string(), argument};
}

std::vector<std::pair<int, std::string>> match_videos_to_cameras(const CameraRig& rig,
                                                                 const std::vector<std::string>& videos) {
  auto find = [&](const std::string& name) {
    for (std::size_t i = 0; i < rig.size(); ++i)
      if (rig[i].name == name) return static_cast<int>(i);
    return -1;
  };
  std::string names;
  for (const Camera& c : rig) names += (names.empty() ? "" : ", ") + c.name;
  std::vector<std::pair<int, std::string>> out;
  std::vector<bool> used(rig.size(), false);
  for (const std::string& v : videos) {
    const auto [name, path] = parse_video_argument(v);
    const int cam = find(name);
    if (cam < 0)
      throw InputError(path, 0, "videos", "no camera named '" + name + "' in the calibration (cameras: " + names +
                                              "); name the camera as NAME=PATH");
    if (used[static_cast<std::size_t>(cam)]) throw InputError(path, 0, "videos", "camera " + name + " given two videos");
    used[static_cast<std::size_t>(cam)] = true;
    out.emplace_back(cam, path);
  }
  return out;
}

Storage capture_quality_table(const CaptureResult& r) {
  std::vector<std::string> labels;
  for (const auto& m : r.markers.marker_names) {
    labels.push_back(m + "_reprojection_px");
    labels.push_back(m + "_views");
  }
  Eigen::MatrixXd data(r.markers.num_frames(), static_cast<Eigen::Index>(labels.size()));
  for (int f = 0; f < r.markers.num_frames(); ++f)
    for (int m = 0; m < r.markers.num_markers(); ++m) {
      data(f, 2 * m) = r.reprojection_px(f, m);
      data(f, 2 * m + 1) = r.views(f, m);
    }
  return make_storage("capture quality (views: 0 missing, 1 single-view pose, -1 gap-filled, n cameras)", labels,
                      r.markers.time_s, data, false);
}

std::string CalibrationSummary::BriefReport() const {
  std::ostringstream s;
  s << "calibration: " << cameras.size() << " cameras, " << board_poses << " board poses, " << observations
    << " corner observations; reprojection RMS " << rms_px << " px (";
  for (std::size_t i = 0; i < cameras.size(); ++i)
    s << (i ? ", " : "") << cameras[i].name << " " << cameras[i].rms_px << " px from " << cameras[i].views << " views";
  s << "); " << iterations << " iterations, " << seconds << " s";
  return s.str();
}

}  // namespace cpgait::video
