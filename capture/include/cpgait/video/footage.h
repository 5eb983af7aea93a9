#pragma once
// The video work that needs OpenCV and AprilTag (decoding, detection, single-view poses,
// calibration) lives in a module of its own, libcpgait_footage.so, which the command line and the
// service load the first time footage is used: commands that touch no video start without OpenCV's
// ~230 shared libraries. Code linked with cpgait_footage calls these functions directly; the rest
// calls them through footage().
#include <string>
#include <utility>
#include <vector>

#include "cpgait/video/calibrate_cameras.h"
#include "cpgait/video/capture_markers.h"

namespace cpgait::video {

// One image's tags, as `cpgait detect` prints them.
struct ImageDetections {
  int width_px = 0, height_px = 0;
  std::vector<TagDetection> tags;
};
// Reads an image file (PNG, JPEG, ...) as grey and detects; InputError when it is not an image.
ImageDetections detect_image_file(const std::string& path, const TagDetectorOptions& options);

// An OpenCV FileStorage calibration (.yml/.yaml/.xml); read_calibration dispatches here.
CameraRig read_opencv_calibration(const std::string& path);

struct FootageFunctions {
  CaptureResult (*capture_markers)(const CameraRig&, const TagSet&, const std::vector<std::string>&, const CaptureOptions&, Progress*);
  std::vector<CameraFootage> (*detect_videos)(const std::vector<std::pair<int, std::string>>&, const TagDetectorOptions&,
                                              const TagTrackerOptions&, double fallback_rate_hz, int threads, Progress*);
  void (*probe_video)(const std::string&);
  CalibrationResult (*calibrate_cameras)(const CalibrationBoard&, const std::vector<CameraFootage>&, const std::vector<std::string>&,
                                         const CalibrationOptions&);
  CameraRig (*read_opencv_calibration)(const std::string&);
  ImageDetections (*detect_image_file)(const std::string&, const TagDetectorOptions&);
};

// The module's functions, loaded on the first call (thread-safe). Looks for the module in
// $CPGAIT_FOOTAGE_MODULE, beside the executable, then where the build put it; throws
// std::runtime_error saying where it looked and why loading failed.
const FootageFunctions& footage();

}  // namespace cpgait::video

// The module's one exported symbol.
extern "C" const cpgait::video::FootageFunctions* cpgait_footage_functions();
