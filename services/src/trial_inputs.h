#pragma once
// A trial's inputs as the pipeline receives them: uploads are held in memory, the CLI reads files.
#include <string>
#include <vector>

namespace cpgait::services {

struct TrialInputs {
  std::string name = "trial";  // output file stem
  std::string model_path;
  std::string generic_model_path;  // optional: the generic model to scale the muscle lengths from
  std::string marker_set_path;  // optional marker-set XML applied to the model
  std::string markers, markers_name;
  // Optional: a static trial; the model is then the generic one, scaled by the scale stage (by a
  // ScaleTool setup's measurements when one is given, else automatically).
  std::string static_markers, static_name;
  std::string scale_setup, scale_setup_name;
  std::string grf, grf_name;      // empty when there are no loads
  std::string loads, loads_name;
  // AprilTag footage instead of markers: one video per camera (NAME=PATH, or a file named after its
  // camera), the cameras' calibration and the tag set, as files.
  std::vector<std::string> videos;
  std::string calibration_path, tags_path;
  bool has_footage() const { return !videos.empty(); }
};

}  // namespace cpgait::services
