#pragma once
// The whole pipeline for one trial (IK -> ID -> SO, more stages as they land), shared by
// `cpgait run` and the server's workers so that both write the same files. Its options are one JSON
// document (job.json) that reproduces a run exactly.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/video/capture_markers.h"

namespace cpgait::services {

// The documented options schema (all keys optional; defaults in brackets):
//   {"model": "<model id>"            server only: which uploaded model
//    "scale_muscles_from": "<model id>"   server only: the uploaded generic model the trial's model
//                                     was scaled from; muscle fibre and tendon lengths are then scaled
//                                     by each path's length ratio, as OpenSim's ScaleTool does (the
//                                     CLI's --scale-muscles-from; see muscles/scale_muscle_parameters.h)
//    "stages": ["ik","id","so"]       [all available]
//    "time_range": [t0, t1]           seconds [the whole trial]
//    "ik": {"bounds": "clamped"|"all"|"none",  ["clamped", as OpenSim]
//           "tasks": {IK task JSON, see capture/ik_setup.h}}   [every marker, weight 1]
//    "id": {"lowpass_cutoff_hz": 6}   [6; negative: no filtering]
//    "so": {"activation_exponent": 2, "use_muscle_physiology": true, "lowpass_cutoff_hz": 6}
//    "cpg": {"pairs": 2, "pattern_units": 2, "foot": "calcn_r"}   a CPG fitted to the SO activations
//                                     over the gait cycles of one foot: heel strikes from the GRF's first
//                                     vertical force (ground_force_vy), else from kinematics (Zeni 2008)
//    "gait": {"duration_s": 2 cycles, "residuals": true}   the reproduced gait (solver/gait): the fitted
//                                     CPG drives the muscles on contact spheres from the first heel
//                                     strike; needs the cpg stage
//    "capture": {"max_reprojection_px": 2, "gap_fill_s": 0.05, "single_view": true,
//                "sync": "index"|"time", "decimate": 3}    only with AprilTag footage (a "capture"
//                                     stage then runs first and its markers feed IK)
//    "inputs": {"model","generic_model","markers","grf","loads": paths}   cpgait run only: what it
//                                     ran on}
struct PipelineOptions {
  std::string model_id;
  std::string scale_muscles_from_id;
  std::vector<std::string> stages = {"ik", "id", "so", "cpg", "gait"};
  std::optional<std::pair<double, double>> time_range_s;
  IkOptions::Bounds ik_bounds = IkOptions::Bounds::kClampedOnly;
  std::optional<nlohmann::json> ik_tasks;
  double id_cutoff_hz = 6.0;
  double so_exponent = 2.0;
  bool so_physiology = true;
  double so_cutoff_hz = 6.0;
  video::CaptureOptions capture;
  int cpg_pairs = 2;
  int cpg_pattern_units = 2;
  std::string cpg_foot;  // empty: calcn_r, else foot_r
  double gait_duration_s = -1;  // negative: two gait cycles (or what the trial has after the start)
  bool gait_residuals = true;
  nlohmann::json inputs = nlohmann::json::object();

  // Throws InputError naming the JSON field ("ik.bounds", ...) for anything invalid or unknown.
  static PipelineOptions from_json(const nlohmann::json& j, const std::string& source);
  static PipelineOptions parse(const std::string& text, const std::string& source);
  nlohmann::json to_json() const;
  bool wants(const std::string& stage) const;
};

extern const std::vector<std::string> kStages;  // in run order (capture runs first when footage is given)

// A trial's inputs as text (uploads are held in memory; the CLI reads files).
struct TrialInputs {
  std::string name = "trial";  // output file stem
  std::string model_path;
  std::string generic_model_path;  // optional: the generic model to scale the muscle lengths from
  std::string marker_set_path;  // optional marker-set XML applied to the model
  std::string markers, markers_name;
  std::string grf, grf_name;      // empty when there are no loads
  std::string loads, loads_name;
  // AprilTag footage instead of markers: one video per camera (NAME=PATH, or a file named after its
  // camera), the cameras' calibration and the tag set, as files.
  std::vector<std::string> videos;
  std::string calibration_path, tags_path;
  bool has_footage() const { return !videos.empty(); }
};

// Where an uploaded trial keeps footage: inputs/videos/<camera>.<ext>, inputs/calibration.<ext>,
// inputs/tags.json. Fills in.videos (NAME=PATH), in.calibration_path and in.tags_path when present.
void load_footage_inputs(const std::string& inputs_dir, TrialInputs& in);

// Checks every input parses (TRC, GRF, loads XML, the model) without running anything; throws
// InputError naming the file, line and field.
void validate_inputs(const TrialInputs& inputs, const PipelineOptions& options);

// What the pipeline reports as it goes; the CLI prints, the server stores and streams.
class PipelineObserver {
 public:
  virtual ~PipelineObserver() = default;
  virtual void stage_started(const std::string& /*stage*/) {}
  virtual void stage_progress(const std::string& /*stage*/, double /*fraction*/) {}
  virtual void stage_finished(const std::string& /*stage*/, double /*seconds*/, const nlohmann::json& /*summary*/) {}
  virtual bool cancelled() const { return false; }
};

struct PipelineResult {
  std::vector<std::string> files;  // written, relative to the output folder
  nlohmann::json summary;          // per stage
};

// Runs the stages into out_dir (created), writing each file atomically, then job.json.
PipelineResult run_pipeline(const TrialInputs& inputs, const PipelineOptions& options, const std::string& out_dir,
                            PipelineObserver* observer = nullptr);

// A file name safe to create: letters, digits, '.', '_' and '-', not starting with '.'.
bool is_safe_file_name(const std::string& name);

}  // namespace cpgait::services
