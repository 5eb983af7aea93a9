#pragma once
// The capture stage for AprilTag footage: decode every camera's video (one thread per video, each
// with its own detector), detect tags, align frames across cameras, triangulate every tag corner
// into a virtual marker. Output is an ordinary MarkerTrial, so IK runs on it as on any TRC.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/progress.h"
#include "cpgait/video/camera.h"
#include "cpgait/video/tag_detector.h"
#include "cpgait/video/tag_set.h"
#include "cpgait/video/tag_tracker.h"
#include "cpgait/video/triangulate.h"

namespace cpgait::video {

struct CaptureOptions {
  TagDetectorOptions detector;  // its family is replaced by the tag set's
  TagTrackerOptions tracker;
  TriangulationOptions triangulation;
  // kIndex: frame i of every camera belongs together. kTime: each camera's frames are placed on the
  // first camera's clock with its calibration's time_offset_s, nearest frame within half a period.
  enum class Sync { kIndex, kTime } sync = Sync::kIndex;
  bool single_view_pose = true;  // a tag seen by one camera only: corners from its IPPE pose...
  double min_pose_ambiguity = 3.0;  // ...unless IPPE's second pose fits within this factor of the first
  // ...or the tag's shortest edge is below this many pixels. A single view's depth error grows as
  // distance x corner noise / edge: at 20 px (an 8 cm tag at 3.5 m, 1300 px focal length) it is
  // 2-5 cm, measured on the rendered footage, which misleads IK more than a missing tag does.
  double min_single_view_edge_px = 60;
  // Gaps (no corner) up to this long with data on both sides are filled by a cubic spline through
  // the neighbouring samples, as gap filling in a marker lab does; 0 turns it off.
  double max_gap_fill_s = 0.05;
  int threads = 0;               // decoding threads; 0 = one per video, at most the hardware's
  double frame_rate_hz = 0;      // used when a video does not state its rate; 0 = required from the video
};

// One camera's footage: its detections per frame.
struct CameraFootage {
  int camera = 0;  // index into the rig
  std::string source;
  double frame_rate_hz = 0;
  int width_px = 0, height_px = 0;
  std::vector<std::vector<TagDetection>> frames;
};

struct CaptureSummary {
  int num_frames = 0;
  std::vector<std::string> cameras;
  std::vector<int> frames_per_camera;
  std::vector<long> detections_per_camera;
  long corners_triangulated = 0;  // from two or more views
  long corners_single_view = 0;   // from one camera's IPPE pose
  long corners_filled = 0;       // markers interpolated across short gaps
  long corners_missing = 0;
  long views_rejected = 0;        // views dropped for reprojection error
  double median_reprojection_px = 0;
  double detect_seconds = 0;
  double triangulate_seconds = 0;
  std::vector<std::string> warnings;
  std::string BriefReport() const;
};

struct CaptureResult {
  MarkerTrial markers;                // tag corners in the lab frame, metres; NaN where missing
  Eigen::MatrixXd reprojection_px;    // frames x markers: RMS reprojection error, NaN where missing
  // frames x markers: cameras used (1 = single-view pose, 0 = missing, -1 = filled across a gap)
  Eigen::MatrixXi views;
  CaptureSummary summary;
};

// A video argument "NAME=PATH", or a PATH whose file stem names the camera: {name, path}.
std::pair<std::string, std::string> parse_video_argument(const std::string& argument);

// Pairs each video with a camera of the rig: "NAME=PATH", or a file whose stem is a camera's name.
// Throws InputError naming the video when no camera matches.
std::vector<std::pair<int, std::string>> match_videos_to_cameras(const CameraRig& rig,
                                                                 const std::vector<std::string>& videos);

// Opens the video and decodes its first frame; throws InputError naming the file otherwise.
void probe_video(const std::string& path);

// Decodes and detects; throws InputError for a video that cannot be opened or decoded.
CameraFootage detect_video(int camera, const std::string& path, const TagDetectorOptions& detector,
                           const TagTrackerOptions& tracker = {}, double fallback_rate_hz = 0);

// detect_video for every (camera, path), one thread per video (up to `threads`, 0: the hardware's).
std::vector<CameraFootage> detect_videos(const std::vector<std::pair<int, std::string>>& videos, const TagDetectorOptions& detector,
                                         const TagTrackerOptions& tracker = {}, double fallback_rate_hz = 0, int threads = 0,
                                         Progress* progress = nullptr);

// Aligns and triangulates already-detected footage (tests and the service feed this directly).
CaptureResult triangulate_footage(const CameraRig& rig, const TagSet& tags, const std::vector<CameraFootage>& footage,
                                  const CaptureOptions& options = {});

// Per frame and marker: RMS reprojection error (px) and the cameras used, as an OpenSim table.
Storage capture_quality_table(const CaptureResult& result);

CaptureResult capture_markers(const CameraRig& rig, const TagSet& tags, const std::vector<std::string>& videos,
                              const CaptureOptions& options = {}, Progress* progress = nullptr);

}  // namespace cpgait::video
