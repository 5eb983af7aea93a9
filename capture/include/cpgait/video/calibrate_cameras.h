#pragma once
// Multi-camera calibration from footage of an AprilTag board: each camera's intrinsics and
// distortion from its own views (OpenCV's calibrateCamera, Zhang's method), extrinsics chained
// through board poses that two cameras see at once, then one bundle adjustment with Ceres over all
// intrinsics, camera poses and board poses (Huber loss). The lab frame is the board's frame at the
// reference frame, placed by `world_from_reference_board` (where the board stood in the lab).
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "cpgait/video/calibration_board.h"
#include "cpgait/video/camera.h"
#include "cpgait/video/capture_markers.h"

namespace cpgait::video {

struct CalibrationOptions {
  int min_tags_per_view = 4;  // fewer board tags in a view: the view is not used
  bool fix_k3 = true;         // k3 is poorly determined unless the board reaches the image corners
  double huber_loss_px = 1.0;
  int reference_frame = -1;   // -1: the first frame seen by the most cameras
  Eigen::Isometry3d world_from_reference_board = Eigen::Isometry3d::Identity();
  int max_iterations = 200;
};

struct CameraCalibrationReport {
  std::string name;
  int views = 0;
  double single_camera_rms_px = 0;  // calibrateCamera's own fit
  double rms_px = 0;                // after the joint bundle adjustment
};

struct CalibrationSummary {
  std::vector<CameraCalibrationReport> cameras;
  double rms_px = 0;
  int board_poses = 0;
  int observations = 0;
  int iterations = 0;
  double seconds = 0;
  std::string BriefReport() const;
};

struct CalibrationResult {
  CameraRig rig;
  std::vector<std::optional<Eigen::Isometry3d>> world_from_board;  // per frame (by the first camera's index)
  CalibrationSummary summary;
};

// `footage[c].camera` indexes `names`; frames are paired by index. Throws InputError when a camera
// has too few usable views or shares no board view with the others.
CalibrationResult calibrate_cameras(const CalibrationBoard& board, const std::vector<CameraFootage>& footage,
                                    const std::vector<std::string>& names, const CalibrationOptions& options = {});

}  // namespace cpgait::video
