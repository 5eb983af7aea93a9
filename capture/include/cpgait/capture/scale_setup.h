#pragma once
// OpenSim's ScaleTool setup: the generic model (GenericModelMaker) and the ModelScaler's
// measurements and manual scales. Paths as written; `setup_dir` is what they are relative to.
#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/ik_setup.h"

namespace cpgait {

struct ScaleMeasurement {
  std::string name;
  int line = 0;  // in the setup, for messages
  std::vector<std::pair<std::string, std::string>> marker_pairs;
  // Bodies the measured factor scales, each along the axes named (X, Y, Z).
  std::vector<std::pair<std::string, std::array<bool, 3>>> body_axes;
};

struct ManualScale {
  std::string body;
  std::array<double, 3> factors{1, 1, 1};
};

struct ScaleSetup {
  std::string name;
  std::string file;  // the setup's path, for messages
  std::string setup_dir;
  double mass_kg = -1;  // the subject's; negative: not given
  // GenericModelMaker
  std::string model_file, marker_set_file;
  // ModelScaler
  bool scaler_apply = true;
  std::vector<std::string> scaling_order;  // "measurements", "manualScale"
  std::vector<ScaleMeasurement> measurements;  // those whose apply is true
  std::vector<ManualScale> manual_scales;      // those whose apply is true
  std::string marker_file;
  std::optional<std::pair<double, double>> time_range_s;
  bool preserve_mass_distribution = false;
  std::string output_model_file, output_scale_file;
  // MarkerPlacer
  bool placer_apply = false;
  IkTaskSet placer_tasks;
  std::string placer_marker_file;
  std::optional<std::pair<double, double>> placer_time_range_s;
  std::string placer_output_model_file, placer_output_motion_file, placer_output_marker_file;
};

// Throws InputError naming the file, line and field for anything malformed.
ScaleSetup read_scale_setup(const std::string& path);
// An uploaded setup: files it names are relative to the current folder.
ScaleSetup parse_scale_setup(std::string content, const std::string& name);

}  // namespace cpgait
