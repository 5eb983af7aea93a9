#include "pipeline.h"

#include <chrono>
#include <filesystem>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/scale_muscle_parameters.h"
#include "output_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Progress of one stage, forwarded to the observer every 5 %.
class StageProgress : public Progress {
 public:
  StageProgress(PipelineObserver* o, std::string stage) : o_(o), stage_(std::move(stage)) {}
  void report(double fraction, std::string_view) override {
    if (o_ && fraction - last_ >= 0.05) {
      last_ = fraction;
      o_->stage_progress(stage_, fraction);
    }
  }
  bool cancelled() const override { return o_ && o_->cancelled(); }

 private:
  PipelineObserver* o_;
  std::string stage_;
  double last_ = 0;
};

// The trial's model (muscle lengths scaled from the generic model when given), its markers (unless
// they come from footage) and its loads; every reader's error names the file, line and field.
// A C3D marker file with force plates and no GRF given: its plates are the trial's loads.
std::optional<GroundReactions> c3d_ground_reactions(const TrialInputs& in) {
  if (!in.grf.empty() || !in.loads.empty() || in.has_footage() || !looks_like_c3d(in.markers)) return std::nullopt;
  const C3dFile file = parse_c3d(in.markers, in.markers_name);
  GroundReactions g = ground_reactions(file, c3d_to_opensim(file, C3dVertical::kAuto));
  if (g.loads.empty()) return std::nullopt;
  return g;
}

StageContext open_trial(const TrialInputs& in, const PipelineOptions& options, const std::string& out_dir,
                        std::optional<GroundReactions>* from_c3d = nullptr) {
  OsimReadOptions ro;
  ro.marker_set_file = in.marker_set_path;
  StageContext trial{in, out_dir, read_osim(in.model_path, ro).model, {}, nullptr, options.time_range_s, {}, {}, nullptr, {}};
  if (!in.generic_model_path.empty()) trial.model = scale_muscle_parameters(trial.model, read_osim(in.generic_model_path).model);
  if (!in.has_footage()) trial.markers = parse_marker_file(in.markers, in.markers_name);
  if (!in.grf.empty() || !in.loads.empty()) {
    if (in.grf.empty()) throw InputError(in.loads_name, 0, "grf", "external loads were given without their GRF data (.mot)");
    if (in.loads.empty()) throw InputError(in.grf_name, 0, "loads", "GRF data were given without the ExternalLoads XML naming the bodies");
    trial.loads = std::make_unique<AppliedLoads>(trial.model, parse_external_loads(in.loads, in.loads_name), parse_storage(in.grf, in.grf_name));
  } else if (auto g = c3d_ground_reactions(in)) {
    trial.loads = std::make_unique<AppliedLoads>(
        trial.model, parse_external_loads(external_loads_document(*g, in.name + "_grf.mot"), in.markers_name + " (force plates)"), g->grf);
    if (from_c3d) *from_c3d = std::move(g);
  }
  return trial;
}

}  // namespace

void StageContext::write(const Storage& table, const std::string& suffix, int digits) {
  write_storage_atomic(table, (fs::path(out_dir) / (inputs.name + suffix)).string(), digits);
  files.push_back(inputs.name + suffix);
}

void StageContext::write_text(const std::string& text, const std::string& suffix) {
  write_text_atomic((fs::path(out_dir) / (inputs.name + suffix)).string(), text);
  files.push_back(inputs.name + suffix);
}

bool is_safe_file_name(const std::string& n) {
  if (n.empty() || n.size() > 200 || n[0] == '.') return false;
  for (char c : n)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) return false;
  return true;
}

void load_footage_inputs(const std::string& inputs_dir, TrialInputs& in) {
  const fs::path dir(inputs_dir);
  if (!fs::is_directory(dir / "videos")) return;
  std::vector<fs::path> videos;
  for (const auto& e : fs::directory_iterator(dir / "videos"))
    if (e.is_regular_file()) videos.push_back(e.path());
  std::sort(videos.begin(), videos.end());
  for (const fs::path& v : videos) in.videos.push_back(v.stem().string() + "=" + v.string());
  for (const char* ext : {".json", ".yml", ".yaml", ".xml"})
    if (fs::exists(dir / (std::string("calibration") + ext))) in.calibration_path = (dir / (std::string("calibration") + ext)).string();
  in.tags_path = (dir / "tags.json").string();
}

void validate_inputs(const TrialInputs& in, const PipelineOptions& options) {
  const StageContext trial = open_trial(in, options, "");
  for (const Stage* stage : options.table())
    if (options.runs(*stage, in)) stage->validate(trial, options.stage_options.at(stage->name()));
  if (options.time_range_s && !in.has_footage()) {
    bool any = false;
    for (double t : trial.markers.time_s) any |= t >= options.time_range_s->first - 1e-9 && t <= options.time_range_s->second + 1e-9;
    if (!any) throw InputError("options", 0, "time_range", "no frame of the trial lies in the requested time range");
  }
}

PipelineResult run_pipeline(const TrialInputs& in, const PipelineOptions& options, const std::string& out_dir,
                            PipelineObserver* observer) {
  ensure_directory(out_dir);
  std::optional<GroundReactions> from_c3d;
  StageContext trial = open_trial(in, options, out_dir, &from_c3d);
  if (from_c3d) {  // the loads the C3D's plates gave, as `cpgait convert` writes them
    from_c3d->grf.name = in.name + "_grf";
    trial.write(from_c3d->grf, "_grf.mot");
    trial.write_text(external_loads_document(*from_c3d, in.name + "_grf.mot"), "_grf.xml");
  }
  PipelineResult result;
  for (const Stage* stage : options.table()) {
    if (!options.runs(*stage, in)) continue;
    const std::string name = stage->name();
    if (observer && observer->cancelled()) throw std::runtime_error("cancelled before the " + name + " stage");
    const auto start = std::chrono::steady_clock::now();
    if (observer) observer->stage_started(name);
    StageProgress progress(observer, name);
    trial.progress = &progress;
    result.summary[name] = stage->run(trial, options.stage_options.at(name));
    trial.progress = nullptr;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (observer) observer->stage_finished(name, seconds, result.summary[name]);
  }
  PipelineOptions recorded = options;
  for (const auto& [stage, values] : trial.recorded_options)
    for (const auto& [key, value] : values.items()) recorded.set_stage_option(stage, key, value, "job.json");
  write_text_atomic((fs::path(out_dir) / "job.json").string(), json_text(recorded.to_json(), 2) + "\n");
  result.files = std::move(trial.files);
  result.files.push_back("job.json");
  return result;
}

}  // namespace cpgait::services
