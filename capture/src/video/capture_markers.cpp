#include "cpgait/video/capture_markers.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <opencv2/videoio.hpp>
#include <sstream>
#include <thread>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/function.h"
#include "cpgait/video/tag_pose.h"

namespace cpgait::video {

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
// Fills runs of missing frames no longer than max_gap_s that have triangulated samples on both
// sides, with an interpolating cubic spline (OpenSim's SimmSpline) through up to four samples each side.
long fill_gaps(CaptureResult& r, double max_gap_s) {
  MarkerTrial& t = r.markers;
  long filled = 0;
  for (int m = 0; m < t.num_markers(); ++m) {
    int f = 0;
    while (f < t.num_frames()) {
      if (r.views(f, m) != 0) {
        ++f;
        continue;
      }
      const int first = f;
      while (f < t.num_frames() && r.views(f, m) == 0) ++f;
      const int last = f - 1;  // gap is [first, last]
      // Only triangulated samples anchor a fill: a single-view pose is too uncertain to extend.
      if (first == 0 || f == t.num_frames() || r.views(first - 1, m) < 2 || r.views(f, m) < 2) continue;
      if (t.time_s[static_cast<std::size_t>(f)] - t.time_s[static_cast<std::size_t>(first - 1)] > max_gap_s + 1e-9) continue;
      std::vector<int> known;
      for (int k = first - 1; k >= 0 && static_cast<int>(known.size()) < 4 && r.views(k, m) >= 2; --k) known.insert(known.begin(), k);
      const std::size_t before = known.size();
      for (int k = f; k < t.num_frames() && known.size() < before + 4 && r.views(k, m) >= 2; ++k) known.push_back(k);
      std::vector<double> x;
      for (int k : known) x.push_back(t.time_s[static_cast<std::size_t>(k)]);
      for (int axis = 0; axis < 3; ++axis) {
        std::vector<double> y;
        for (int k : known) y.push_back(t.position_m(k, m)[axis]);
        const Function spline = known.size() >= 3 ? Function::simm_spline(x, y) : Function::piecewise_linear(x, y);
        for (int g = first; g <= last; ++g) t.position_m(g, m)[axis] = spline.value(t.time_s[static_cast<std::size_t>(g)]);
      }
      for (int g = first; g <= last; ++g) r.views(g, m) = -1;
      filled += last - first + 1;
    }
  }
  return filled;
}

}  // namespace

void probe_video(const std::string& path) {
  if (!std::filesystem::exists(path)) throw InputError(path, 0, "videos", "file not found");
  cv::VideoCapture video(path, cv::CAP_FFMPEG);
  cv::Mat frame;
  if (!video.isOpened() || !video.read(frame) || frame.empty())
    throw InputError(path, 0, "videos", "cannot decode as a video (FFmpeg could not read a frame)");
}

CameraFootage detect_video(int camera, const std::string& path, const TagDetectorOptions& detector_options,
                           const TagTrackerOptions& tracker_options, double fallback_rate_hz) {
  if (!std::filesystem::exists(path)) throw InputError(path, 0, "videos", "file not found");
  cv::VideoCapture video(path, cv::CAP_FFMPEG);  // FFmpeg only: no GStreamer probing of bad files
  if (!video.isOpened()) throw InputError(path, 0, "videos", "cannot open as a video (FFmpeg could not decode it)");
  CameraFootage f;
  f.camera = camera;
  f.source = path;
  f.frame_rate_hz = video.get(cv::CAP_PROP_FPS);
  if (!(f.frame_rate_hz > 0 && f.frame_rate_hz < 10000)) f.frame_rate_hz = fallback_rate_hz;
  if (!(f.frame_rate_hz > 0))
    throw InputError(path, 0, "frame_rate_hz", "the video states no frame rate; give one in the options");
  TagTracker tracker(detector_options, tracker_options);
  cv::Mat frame;
  while (video.read(frame)) {
    if (frame.empty()) break;
    f.width_px = frame.cols;
    f.height_px = frame.rows;
    f.frames.push_back(tracker.detect(frame));
  }
  if (f.frames.empty()) throw InputError(path, 0, "videos", "no decodable frames");
  return f;
}

CaptureResult triangulate_footage(const CameraRig& rig, const TagSet& tags, const std::vector<CameraFootage>& footage,
                                  const CaptureOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CaptureResult r;
  CaptureSummary& s = r.summary;
  if (footage.empty()) throw InputError("videos", 0, "videos", "no footage given");
  const CameraFootage& ref = footage.front();
  for (const CameraFootage& f : footage) {
    s.cameras.push_back(rig[static_cast<std::size_t>(f.camera)].name);
    s.frames_per_camera.push_back(static_cast<int>(f.frames.size()));
    long n = 0;
    for (const auto& fr : f.frames) n += static_cast<long>(fr.size());
    s.detections_per_camera.push_back(n);
  }
  // Frame alignment: for every reference frame, the frame index of each camera (-1 = none).
  int num_frames = static_cast<int>(ref.frames.size());
  if (options.sync == CaptureOptions::Sync::kIndex) {
    for (const CameraFootage& f : footage) num_frames = std::min(num_frames, static_cast<int>(f.frames.size()));
    for (std::size_t c = 0; c < footage.size(); ++c)
      if (static_cast<int>(footage[c].frames.size()) != static_cast<int>(ref.frames.size()))
        s.warnings.push_back("camera " + s.cameras[c] + " has " + std::to_string(footage[c].frames.size()) +
                             " frames, camera " + s.cameras[0] + " " + std::to_string(ref.frames.size()) +
                             "; frames are paired by index, so only the first " + std::to_string(num_frames) + " are used");
  }
  const double ref_offset = rig[static_cast<std::size_t>(ref.camera)].time_offset_s;
  auto frame_of = [&](std::size_t c, int i) -> int {
    const CameraFootage& f = footage[c];
    if (options.sync == CaptureOptions::Sync::kIndex) return i;
    const double t = i / ref.frame_rate_hz - ref_offset;  // reference clock
    const double j = (t + rig[static_cast<std::size_t>(f.camera)].time_offset_s) * f.frame_rate_hz;
    const long k = std::lround(j);
    if (k < 0 || k >= static_cast<long>(f.frames.size()) || std::abs(j - static_cast<double>(k)) > 0.5) return -1;
    return static_cast<int>(k);
  };

  // Tags seen that the set does not list: one warning per camera and id.
  std::map<std::pair<std::size_t, int>, int> unknown;
  for (std::size_t c = 0; c < footage.size(); ++c)
    for (const auto& fr : footage[c].frames)
      for (const TagDetection& d : fr)
        if (!tags.find(d.id)) ++unknown[{c, d.id}];
  for (const auto& [key, n] : unknown)
    s.warnings.push_back("tag " + std::to_string(key.second) + " seen by camera " + s.cameras[key.first] + " in " +
                         std::to_string(n) + " frames is not in the tag set; ignored");

  const std::vector<std::string> names = tags.marker_names();
  const int M = static_cast<int>(names.size());
  MarkerTrial& trial = r.markers;
  trial.name = "capture";
  trial.marker_names = names;
  trial.data_rate_hz = trial.camera_rate_hz = trial.orig_data_rate_hz = ref.frame_rate_hz;
  trial.orig_num_frames = num_frames;
  trial.positions_m.setConstant(3, static_cast<Eigen::Index>(num_frames) * M, std::numeric_limits<double>::quiet_NaN());
  r.reprojection_px.setConstant(num_frames, M, std::numeric_limits<double>::quiet_NaN());
  r.views.setZero(num_frames, M);
  std::vector<double> residuals;
  for (int i = 0; i < num_frames; ++i) {
    trial.time_s.push_back(i / ref.frame_rate_hz);
    trial.frame_numbers.push_back(i + 1);
    // Pass 1: triangulate every corner seen by two or more cameras.
    std::vector<std::vector<std::pair<std::size_t, const TagDetection*>>> seen(tags.tags.size());
    for (std::size_t t = 0; t < tags.tags.size(); ++t) {
      for (std::size_t c = 0; c < footage.size(); ++c) {
        const int j = frame_of(c, i);
        if (j < 0) continue;
        for (const TagDetection& d : footage[c].frames[static_cast<std::size_t>(j)])
          if (d.id == tags.tags[t].id) seen[t].emplace_back(c, &d);
      }
      if (seen[t].size() < 2) continue;
      for (int k = 0; k < 4; ++k) {
        const int m = static_cast<int>(4 * t) + k;
        std::vector<PixelObservation> obs;
        for (const auto& [c, d] : seen[t]) obs.push_back({footage[c].camera, d->corners_px[static_cast<std::size_t>(k)]});
        const TriangulatedPoint p = triangulate_point(rig, obs, options.triangulation);
        s.views_rejected += static_cast<long>(p.rejected_cameras.size());
        if (!p.valid()) continue;
        trial.position_m(i, m) = p.position_m;
        r.reprojection_px(i, m) = p.rms_reprojection_px;
        r.views(i, m) = p.views_used;
        residuals.push_back(p.rms_reprojection_px);
        ++s.corners_triangulated;
      }
    }
    // Pass 2: a body left with fewer than three triangulated corners gets its tags' single-view
    // (IPPE) poses. Single-view depth is good to about a centimetre at 3 m, so these corners only
    // stand in where the body would otherwise be lost, never beside triangulated ones.
    if (!options.single_view_pose) continue;
    std::map<std::string, int> body_corners;
    for (std::size_t t = 0; t < tags.tags.size(); ++t)
      for (int k = 0; k < 4; ++k) body_corners[tags.tags[t].body] += r.views(i, static_cast<int>(4 * t) + k) >= 2;
    for (std::size_t t = 0; t < tags.tags.size(); ++t) {
      const TagMount& mount = tags.tags[t];
      if (seen[t].empty() || body_corners[mount.body] >= 3) continue;
      const auto best = std::max_element(seen[t].begin(), seen[t].end(), [](const auto& a, const auto& b) {
        return a.second->decision_margin < b.second->decision_margin;
      });
      const Camera& cam = rig[static_cast<std::size_t>(footage[best->first].camera)];
      const TagPose pose = tag_pose_ippe(cam, *best->second, mount.size_m);
      if (!(pose.rms_reprojection_px <= options.triangulation.max_reprojection_error_px)) continue;
      if (pose.ambiguity < options.min_pose_ambiguity) continue;
      const auto& px = best->second->corners_px;
      const double edge_px = std::min({(px[0] - px[1]).norm(), (px[1] - px[2]).norm(), (px[2] - px[3]).norm(), (px[3] - px[0]).norm()});
      if (edge_px < options.min_single_view_edge_px) continue;
      const auto corners = tag_corners_in_tag_frame(mount.size_m);
      for (int k = 0; k < 4; ++k) {
        const int m = static_cast<int>(4 * t) + k;
        if (r.views(i, m) != 0) continue;
        const Eigen::Vector3d p_cam = pose.rotation_cam_from_tag * corners[static_cast<std::size_t>(k)] + pose.translation_cam_from_tag_m;
        trial.position_m(i, m) = cam.rotation_cam_from_world.transpose() * (p_cam - cam.translation_cam_from_world_m);
        r.reprojection_px(i, m) = pose.rms_reprojection_px;
        r.views(i, m) = 1;
        ++s.corners_single_view;
      }
    }
  }
  // Centre markers: the mean of the tag's four corners where all four exist (views: the fewest).
  for (int i = 0; i < num_frames; ++i)
    for (std::size_t t = 0, m = 4 * tags.tags.size(); t < tags.tags.size(); ++t) {
      if (tags.tags[t].center_marker.empty()) continue;
      int views = 1 << 20;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      double rms = 0;
      for (int k = 0; k < 4; ++k) {
        const int c = static_cast<int>(4 * t) + k;
        views = std::min(views, r.views(i, c));
        sum += trial.position_m(i, c);
        rms = std::max(rms, r.reprojection_px(i, c));
      }
      if (views > 0) {
        trial.position_m(i, m) = sum / 4;
        r.views(i, m) = views;
        r.reprojection_px(i, m) = rms;
      }
      ++m;  // centre markers follow every corner, in tag order
    }
  s.num_frames = num_frames;
  if (options.max_gap_fill_s > 0) s.corners_filled = fill_gaps(r, options.max_gap_fill_s);
  s.corners_missing = 0;
  for (int c = 0; c < 4 * static_cast<int>(tags.tags.size()); ++c) s.corners_missing += (r.views.col(c).array() == 0).count();
  if (!residuals.empty()) {
    std::nth_element(residuals.begin(), residuals.begin() + static_cast<long>(residuals.size() / 2), residuals.end());
    s.median_reprojection_px = residuals[residuals.size() / 2];
  }
  for (int m = 0; m < M; ++m)
    if ((r.views.col(m).array() == 0).all())
      s.warnings.push_back("marker " + names[static_cast<std::size_t>(m)] + " was never seen by enough cameras");
  s.triangulate_seconds = seconds_since(t0);
  trial.warnings = s.warnings;
  return r;
}

std::vector<CameraFootage> detect_videos(const std::vector<std::pair<int, std::string>>& videos, const TagDetectorOptions& detector,
                                         const TagTrackerOptions& tracker, double fallback_rate_hz, int threads, Progress* progress) {
  std::vector<CameraFootage> footage(videos.size());
  std::vector<std::exception_ptr> errors(videos.size());
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex progress_mutex;
  auto work = [&] {
    for (std::size_t i; (i = next++) < videos.size();) {
      try {
        footage[i] = detect_video(videos[i].first, videos[i].second, detector, tracker, fallback_rate_hz);
      } catch (...) {
        errors[i] = std::current_exception();
      }
      const std::lock_guard lock(progress_mutex);
      if (progress) progress->report(0.9 * static_cast<double>(++done) / static_cast<double>(videos.size()), "detecting tags");
    }
  };
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t n_threads = std::min<std::size_t>(videos.size(), threads > 0 ? static_cast<unsigned>(threads) : hw);
  std::vector<std::thread> pool;
  for (std::size_t k = 1; k < n_threads; ++k) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  return footage;
}

CaptureResult capture_markers(const CameraRig& rig, const TagSet& tags, const std::vector<std::string>& videos,
                              const CaptureOptions& options, Progress* progress) {
  const auto t0 = std::chrono::steady_clock::now();
  TagDetectorOptions detector = options.detector;
  detector.family = tags.family;
  const std::vector<CameraFootage> footage = detect_videos(match_videos_to_cameras(rig, videos), detector, options.tracker,
                                                           options.frame_rate_hz, options.threads, progress);
  const double detect_s = seconds_since(t0);
  CaptureResult r = triangulate_footage(rig, tags, footage, options);
  r.summary.detect_seconds = detect_s;
  if (progress) progress->report(1.0, "triangulated");
  return r;
}

}  // namespace cpgait::video
