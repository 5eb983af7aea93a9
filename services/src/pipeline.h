#pragma once
// The whole pipeline for one trial, shared by `cpgait run` and the server's workers so that both
// write the same files: a table of stages (stage.h) walked in order. Its options are one JSON
// document (job.json) that reproduces a run exactly; `cpgait run --print-options-schema` and
// GET /api/v1/options/schema publish its JSON Schema, made from the same definitions that read it.
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "stage.h"
#include "trial_inputs.h"

namespace cpgait::services {

struct PipelineOptions {
  explicit PipelineOptions(const StageTable& table = pipeline_stages());

  std::string model_id;               // "model": server only, which uploaded model
  std::string scale_muscles_from_id;  // "scale_muscles_from": server only, the generic model
  std::string activation = "so";      // "activation": the activation stage that runs ["so"]
  std::vector<std::string> stages;    // "stages": the selectable stages to run [all of them]
  std::optional<std::pair<double, double>> time_range_s;  // "time_range" [the whole trial]
  nlohmann::json inputs = nlohmann::json::object();        // "inputs": cpgait run only, what it ran on
  std::map<std::string, nlohmann::json> stage_options;    // each stage's options object, complete

  const StageTable& table() const { return *table_; }
  bool wants(const std::string& stage) const;
  // A stage's need by name: "activation" is the activation stage the options pick.
  std::string resolve_need(const std::string& need) const { return need == "activation" ? activation : need; }
  // Whether the stage runs on this trial: it applies to the inputs and, if selectable, is wanted.
  bool runs(const Stage& stage, const TrialInputs& inputs) const;
  // Sets one option of a stage, checked as if the document had it (InputError names "<stage>.<key>").
  void set_stage_option(const std::string& stage, const std::string& key, const nlohmann::json& value, const std::string& source);

  // Throws InputError naming the JSON field ("ik.bounds", ...) for anything invalid or unknown.
  static PipelineOptions from_json(const nlohmann::json& j, const std::string& source, const StageTable& table = pipeline_stages());
  static PipelineOptions parse(const std::string& text, const std::string& source, const StageTable& table = pipeline_stages());
  nlohmann::json to_json() const;

 private:
  const StageTable* table_;
};

// The options document's JSON Schema (2020-12): stages, fields, types, defaults, units, descriptions.
nlohmann::json pipeline_options_schema(const StageTable& table = pipeline_stages());
// The stages in run order, each with what it needs and writes (GET /api/v1/stages).
nlohmann::json pipeline_stages_json(const StageTable& table = pipeline_stages());
// The stage of that name, or null.
const Stage* find_stage(const std::string& name, const StageTable& table = pipeline_stages());

// Where an uploaded trial keeps footage: inputs/videos/<camera>.<ext>, inputs/calibration.<ext>,
// inputs/tags.json. Fills in.videos (NAME=PATH), in.calibration_path and in.tags_path when present.
void load_footage_inputs(const std::string& inputs_dir, TrialInputs& in);

// Checks every input parses (TRC, GRF, loads XML, the model, each stage's own checks) without
// running anything; throws InputError naming the file, line and field.
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
