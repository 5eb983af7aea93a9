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
  // Optional OpenSim CMC files for the cmc stage: its task set, its actuators (a ForceSet, added to
  // the model's own) and control constraints (a ControlSet). Absent: derived from the model.
  std::string cmc_tasks, cmc_tasks_name, cmc_actuators, cmc_actuators_name, cmc_constraints, cmc_constraints_name;
  // AprilTag footage instead of markers: one video per camera (NAME=PATH, or a file named after its
  // camera), the cameras' calibration and the tag set, as files.
  std::vector<std::string> videos;
  std::string calibration_path, tags_path;
  bool has_footage() const { return !videos.empty(); }
};

// The cmc stage's optional files: each one's upload part (also its key in job.json's inputs and
// its file inputs/<part>.xml on the server), contents and name.
struct CmcFilePart {
  const char* part;
  std::string TrialInputs::*content;
  std::string TrialInputs::*name;
};
inline constexpr CmcFilePart kCmcFileParts[] = {{"cmc_tasks", &TrialInputs::cmc_tasks, &TrialInputs::cmc_tasks_name},
                                                {"cmc_actuators", &TrialInputs::cmc_actuators, &TrialInputs::cmc_actuators_name},
                                                {"cmc_constraints", &TrialInputs::cmc_constraints, &TrialInputs::cmc_constraints_name}};

}  // namespace cpgait::services
