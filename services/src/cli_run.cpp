// run: every available stage on one trial, as the server runs it; job.json reproduces the run.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iterator>

#include "commands.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/ik_setup.h"
#include "cpgait/video/capture_markers.h"
#include "pipeline.h"
#include "output_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

class PrintingObserver : public PipelineObserver {
 public:
  void stage_started(const std::string&) override { started_ = std::chrono::steady_clock::now(); }
  // To stderr, once a stage has run a second (the gait stage's tuning runs for minutes).
  void stage_progress(const std::string& stage, double fraction) override {
    if (std::chrono::steady_clock::now() - started_ < std::chrono::seconds(1)) return;
    std::fprintf(stderr, "%s %3.0f %%\n", stage.c_str(), 100 * fraction);
  }
  void stage_finished(const std::string& stage, double seconds, const nlohmann::json& summary) override {
    std::printf("%-3s done in %.3f s: %s\n", stage.c_str(), seconds, json_text(summary).c_str());
  }

 private:
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
};

struct RunArgs {
  std::string model, generic_model, ik_tasks, markers, grf, loads, options, name, out, calibration, tags;
  std::string scale_from, static_trial, scale_setup, marker_set;
  std::string cmc_tasks, cmc_actuators, cmc_constraints;
  std::vector<std::string> videos;
  bool print_schema = false;
};

// The trial's inputs: the command line, else the paths the options recorded; recorded back into
// options.inputs so that job.json reruns from anywhere.
TrialInputs resolve_inputs(const RunArgs& a, PipelineOptions& options) {
  auto input = [&](const std::string& given, const char* key) {
    if (!given.empty()) return fs::absolute(given).string();
    if (options.inputs.contains(key) && options.inputs[key].is_string()) return options.inputs[key].get<std::string>();
    return std::string();
  };
  TrialInputs in;
  if (!a.model.empty() && !a.scale_from.empty()) throw InputError("cpgait run", 0, "--generic-model", "give --model or --generic-model, not both");
  in.model_path = input(a.scale_from.empty() ? a.model : a.scale_from, "model");
  in.marker_set_path = input(a.marker_set, "marker_set");
  const std::string static_trial = input(a.static_trial, "static"), scale_setup = input(a.scale_setup, "scale_setup");
  if (!a.scale_from.empty() && static_trial.empty()) throw InputError("cpgait run", 0, "--static", "--generic-model needs the static trial");
  if (!static_trial.empty()) {
    in.static_markers = text::read_file(static_trial);
    in.static_name = static_trial;
  }
  if (!scale_setup.empty()) {
    if (static_trial.empty()) throw InputError("cpgait run", 0, "--static", "--scale-setup needs the static trial");
    in.scale_setup = text::read_file(scale_setup);
    in.scale_setup_name = scale_setup;
  }
  in.generic_model_path = input(a.generic_model, "generic_model");
  const std::string markers = input(a.markers, "markers");
  const std::string grf = input(a.grf, "grf"), loads = input(a.loads, "loads");
  in.calibration_path = input(a.calibration, "calibration");
  in.tags_path = input(a.tags, "tags");
  if (!a.videos.empty()) {
    for (const std::string& v : a.videos) {
      const auto [camera, path] = video::parse_video_argument(v);
      in.videos.push_back(camera + "=" + fs::absolute(path).string());  // job.json then works from anywhere
    }
  } else if (options.inputs.contains("videos") && options.inputs["videos"].is_array()) {
    for (const auto& v : options.inputs["videos"]) {
      if (!v.is_string()) throw InputError(a.options, 0, "inputs.videos", "expected camera=path strings, as --video takes them");
      in.videos.push_back(v.get<std::string>());
    }
  }
  if (in.model_path.empty() || (markers.empty() && !in.has_footage()))
    throw InputError(a.options.empty() ? "cpgait run" : a.options, 0, "inputs",
                     "give --model and --markers, or --model with --videos, --calibration and --tags (or options that record them)");
  if (in.has_footage() && (in.calibration_path.empty() || in.tags_path.empty()))
    throw InputError("cpgait run", 0, in.calibration_path.empty() ? "calibration" : "tags", "--videos needs --calibration and --tags");
  if (!in.has_footage()) {
    in.markers = text::read_file(markers);
    in.markers_name = markers;
  }
  if (!grf.empty()) in.grf = text::read_file(grf), in.grf_name = grf;
  if (!loads.empty()) in.loads = text::read_file(loads), in.loads_name = loads;
  // The cmc stage's OpenSim files, read now and recorded below like the other inputs.
  const std::string* cmc_given[] = {&a.cmc_tasks, &a.cmc_actuators, &a.cmc_constraints};
  for (std::size_t k = 0; k < std::size(kCmcFileParts); ++k)
    if (const std::string path = input(*cmc_given[k], kCmcFileParts[k].part); !path.empty())
      in.*kCmcFileParts[k].content = text::read_file(path), in.*kCmcFileParts[k].name = path;
  in.name = !a.name.empty() ? a.name
            : options.inputs.contains("name") ? options.inputs["name"].get<std::string>()
                                              : in.has_footage() ? std::string("capture") : fs::path(markers).stem().string();
  if (!is_safe_file_name(in.name)) throw InputError("cpgait run", 0, "name", "output stem '" + in.name + "' is not a safe file name");
  options.inputs = {{"model", in.model_path}, {"name", in.name}};
  if (!in.generic_model_path.empty()) options.inputs["generic_model"] = in.generic_model_path;
  if (!in.marker_set_path.empty()) options.inputs["marker_set"] = in.marker_set_path;
  if (!static_trial.empty()) options.inputs["static"] = static_trial;
  if (!scale_setup.empty()) options.inputs["scale_setup"] = scale_setup;
  if (in.has_footage()) {
    options.inputs["videos"] = in.videos;
    options.inputs["calibration"] = in.calibration_path;
    options.inputs["tags"] = in.tags_path;
  } else {
    options.inputs["markers"] = markers;
  }
  if (!grf.empty()) options.inputs["grf"] = grf;
  if (!loads.empty()) options.inputs["loads"] = loads;
  for (const CmcFilePart& f : kCmcFileParts)
    if (!(in.*f.name).empty()) options.inputs[f.part] = in.*f.name;
  return in;
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto* run = app.add_subcommand(
      "run",
      "Run every stage on one trial (IK, then ID, then static optimization), as the server does.\n"
      "Inputs: .osim model (or a generic model with the subject's static trial: a scale stage first scales it),\n"
      ".trc or .c3d markers (or AprilTag videos with their calibration and tag set: a capture\n"
      "stage then makes the markers), optional GRF .mot with its ExternalLoads .xml, optional options\n"
      "JSON (its JSON Schema: --print-options-schema). Writes all result files and job.json (the exact\n"
      "options and input paths) into DIR; `cpgait run --options DIR/job.json -o DIR2` reproduces them.");
  auto a = std::make_shared<RunArgs>();
  run->add_option("--model", a->model, "OpenSim model (.osim)")->check(CLI::ExistingFile);
  run->add_option("--scale-muscles-from", a->generic_model,
                  "generic .osim the model was scaled from: muscle fibre and tendon lengths scaled as OpenSim's ScaleTool does")
      ->check(CLI::ExistingFile);
  run->add_option("--generic-model", a->scale_from,
                  "a generic .osim to scale to the subject first (needs --static; instead of --model): the scale stage")
      ->check(CLI::ExistingFile);
  run->add_option("--static", a->static_trial, "the subject's static trial (.trc or .c3d) for --generic-model")->check(CLI::ExistingFile);
  run->add_option("--scale-setup", a->scale_setup,
                  "an OpenSim ScaleTool setup whose measurements, manual scales and MarkerPlacer tasks scale the generic "
                  "model (its file names are not used); absent: automatic scaling")
      ->check(CLI::ExistingFile);
  run->add_option("--marker-set", a->marker_set, "a marker-set XML replacing/adding the model's markers")->check(CLI::ExistingFile);
  run->add_option("--markers", a->markers, "marker trajectories (.trc or .c3d)")->check(CLI::ExistingFile);
  run->add_option("--videos", a->videos, "AprilTag footage instead of --markers: one video per camera (NAME=PATH or named after it)");
  run->add_option("--calibration", a->calibration, "camera calibration for --videos (.json or OpenCV .yml)")->check(CLI::ExistingFile);
  run->add_option("--tags", a->tags, "tag set for --videos (.json)")->check(CLI::ExistingFile);
  run->add_option("--grf", a->grf, "ground reaction forces (.mot)")->check(CLI::ExistingFile);
  run->add_option("--loads", a->loads, "ExternalLoads .xml for the GRF")->check(CLI::ExistingFile);
  run->add_option("--cmc-tasks", a->cmc_tasks, "an OpenSim CMC task set .xml for the cmc stage (absent: every unlocked coordinate)")
      ->check(CLI::ExistingFile);
  run->add_option("--cmc-actuators", a->cmc_actuators,
                  "an OpenSim actuator ForceSet .xml for the cmc stage, added to the model's (absent: weak residuals and reserves)")
      ->check(CLI::ExistingFile);
  run->add_option("--cmc-constraints", a->cmc_constraints, "an OpenSim control-constraints ControlSet .xml for the cmc stage")
      ->check(CLI::ExistingFile);
  run->add_option("--ik-tasks", a->ik_tasks,
                  "IK task weights for the ik stage: an IKTaskSet .xml (or an IK setup's), or the .json equivalent; kept in "
                  "job.json as ik.tasks")
      ->check(CLI::ExistingFile);
  run->add_option("--options", a->options, "options JSON (e.g. a previous job.json)")->check(CLI::ExistingFile);
  run->add_option("--name", a->name, "output file stem (default: the marker file's name)");
  run->add_option("-o,--output", a->out, "output folder (required unless --print-options-schema)");
  run->add_flag("--print-options-schema", a->print_schema,
                "print the options document's JSON Schema (every stage's fields, types, defaults, units) and exit");
  run->callback([a] {
    if (a->print_schema) {
      std::printf("%s\n", json_text(pipeline_options_schema(), 2).c_str());
      return;
    }
    if (a->out.empty()) throw CLI::RequiredError("--output");
    PipelineOptions options = a->options.empty() ? PipelineOptions() : PipelineOptions::parse(text::read_file(a->options), a->options);
    if (!a->ik_tasks.empty())
      options.set_stage_option("ik", "tasks", nlohmann::json::parse(ik_tasks_json(read_ik_tasks(a->ik_tasks))), a->ik_tasks);
    const TrialInputs in = resolve_inputs(*a, options);
    validate_inputs(in, options);
    PrintingObserver observer;
    const PipelineResult r = run_pipeline(in, options, a->out, &observer);
    for (const auto& f : r.files) std::printf("wrote %s\n", (fs::path(a->out) / f).string().c_str());
  });
}

}  // namespace cpgait::services
