// Scale: the generic model scaled to the subject from a static trial - by a ScaleTool setup's
// measurements when one is given, else automatically - and its markers placed; every later stage
// uses the scaled model. Runs first, and only when the trial comes with a static trial.
#include <map>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/scale_setup.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/osim_writer.h"
#include "cpgait/scaling/fit_scale_factors.h"
#include "cpgait/scaling/model_scale_factors.h"
#include "cpgait/scaling/place_markers.h"
#include "cpgait/scaling/scale_model.h"
#include "ik_tasks_field.h"
#include "stage.h"

namespace cpgait::services {
namespace {

struct ScaleStageOptions {
  std::optional<double> mass_kg;
  bool symmetric = true;
  bool per_axis = false;
  std::optional<nlohmann::json> tasks;
  std::map<std::string, std::array<double, 3>> factors;

  IkTaskSet task_set() const { return tasks ? parse_ik_tasks_json(tasks->dump(), "options (scale.tasks)") : IkTaskSet{}; }

  static const OptionFields<ScaleStageOptions>& fields() {
    static const OptionFields<ScaleStageOptions> f =
        OptionFields<ScaleStageOptions>(
            "The model in `model` is the generic one. With a ScaleTool setup, its measurements and manual scales (OpenSim's "
            "Scale tool); without, automatic: per-body factors, marker offsets and the static pose fitted together. Markers "
            "are then placed on the static trial.")
            .optional_number("mass_kg", &ScaleStageOptions::mass_kg, "kg",
                             "the subject's mass: the bodies' masses keep their shares of it (absent: the setup's, or masses "
                             "scaled with the bodies)",
                             NumberRange{0.0, {}, true})
            .boolean("symmetric", &ScaleStageOptions::symmetric, "automatic: left and right bodies (_r, _l) share their factors")
            .boolean("per_axis", &ScaleStageOptions::per_axis, "automatic: a factor per body axis instead of one per body")
            .add(ik_tasks_field(&ScaleStageOptions::tasks,
                                "marker weights on the static trial, as ik.tasks (absent: the setup's MarkerPlacer "
                                   "tasks, or every marker weight 1)"))
            .add({"factors",
                  {{"type", "object"},
                   {"additionalProperties", {{"type", "array"}, {"items", {{"type", "number"}}}, {"minItems", 3}, {"maxItems", 3}}},
                   {"description", "body -> [x, y, z] scale factors to use instead of computing them; a run records the "
                                   "ones it computed here, so that its job.json reproduces it"}},
                  [](const nlohmann::json& v, ScaleStageOptions& o, const OptionPath& p) {
                    if (!v.is_object()) p.fail("factors", "expected an object of body: [x, y, z]");
                    for (const auto& [body, xyz] : v.items()) {
                      if (!xyz.is_array() || xyz.size() != 3) p.fail("factors." + body, "expected [x, y, z]");
                      std::array<double, 3> a{};
                      for (int k = 0; k < 3; ++k) {
                        if (!xyz[k].is_number() || !(xyz[k].get<double>() >= kMinScaleFactor && xyz[k].get<double>() <= kMaxScaleFactor))
                          p.fail("factors." + body, "scale factors must be numbers within 0.5-2");
                        a[static_cast<std::size_t>(k)] = xyz[k].get<double>();
                      }
                      o.factors[body] = a;
                    }
                  },
                  [](const ScaleStageOptions& o, nlohmann::json& j) {
                    if (o.factors.empty()) return;
                    nlohmann::json f = nlohmann::json::object();
                    for (const auto& [body, a] : o.factors) f[body] = a;
                    j["factors"] = f;
                  }});
    return f;
  }
};

class ScaleStage final : public StageWithOptions<ScaleStageOptions> {
 public:
  std::string name() const override { return "scale"; }
  std::string description() const override { return "scaling: the generic model fitted to the subject's static trial"; }
  std::vector<std::string> writes() const override { return {"_scaled.osim", "_scale_factors.sto", "_static_marker_errors.sto"}; }
  std::vector<std::string> tables() const override { return {"_scale_factors.sto", "_static_marker_errors.sto"}; }
  bool applies(const TrialInputs& in) const override { return !in.static_markers.empty(); }
  bool selectable() const override { return false; }

 protected:
  void check(const StageContext& trial, const ScaleStageOptions& o) const override {
    const TrialInputs& in = trial.inputs;
    const MarkerTrial st = parse_marker_file(in.static_markers, in.static_name);
    for (const auto& [body, a] : o.factors)
      if (trial.model.body_index(body) < 0) throw InputError("options", 0, "scale.factors." + body, "the model has no body '" + body + "'");
    if (!in.scale_setup.empty()) {
      const ScaleSetup setup = parse_scale_setup(in.scale_setup, in.scale_setup_name);
      if (o.factors.empty()) model_scale_factors(trial.model, setup, &st);
    } else {
      make_ik_targets(trial.model, average_static_frame(st, {}), o.task_set(), IkOptions{});
    }
  }

  nlohmann::json execute(StageContext& trial, const ScaleStageOptions& o) const override {
    const TrialInputs& in = trial.inputs;
    const Model& generic = trial.model;
    const MarkerTrial st = parse_marker_file(in.static_markers, in.static_name);
    std::optional<ScaleSetup> setup;
    if (!in.scale_setup.empty()) setup = parse_scale_setup(in.scale_setup, in.scale_setup_name);
    const IkTaskSet tasks = o.tasks || !setup ? o.task_set() : setup->placer_tasks;
    const auto range = setup ? setup->placer_time_range_s : std::nullopt;
    const double mass = o.mass_kg ? *o.mass_kg : setup ? setup->mass_kg : -1.0;
    const bool preserve = setup ? setup->preserve_mass_distribution : true;
    std::vector<Eigen::Vector3d> factors(generic.bodies.size(), Eigen::Vector3d::Ones());
    std::string method;
    nlohmann::json summary;
    std::vector<std::string> warnings;
    if (!o.factors.empty()) {
      method = "given factors";
      for (const auto& [body, a] : o.factors) factors[static_cast<std::size_t>(generic.body_index(body))] = Eigen::Vector3d(a[0], a[1], a[2]);
    } else if (setup) {
      method = "ScaleTool setup";
      const ModelScaleFactors f = model_scale_factors(generic, *setup, &st);
      factors = f.body;
      warnings = f.warnings;
    } else {
      method = "automatic";
      ScaleFitOptions fo;
      fo.symmetric = o.symmetric;
      fo.per_axis = o.per_axis;
      const ScaleFit fit = fit_scale_factors(generic, st, tasks, {}, fo);
      factors = fit.factors;
      warnings = fit.summary.warnings;
      summary["fit"] = {{"iterations", fit.summary.iterations},
                        {"seconds", fit.summary.seconds},
                        {"static_rms_generic_m", fit.summary.static_rms_generic_m}};
    }
    const Model scaled = scale_model(generic, factors, preserve, mass);
    const MarkerPlacement p = place_markers(scaled, st, tasks, range);
    for (const auto& w : p.warnings) warnings.push_back(w);
    trial.model = p.model;
    trial.write_text(osim_document(p.model, {in.name, ""}), "_scaled.osim");
    trial.write(factors_table(generic, factors), "_scale_factors.sto");
    trial.write(static_errors_table(scaled, st, tasks, range, p), "_static_marker_errors.sto");
    nlohmann::json recorded = nlohmann::json::object(), per_body = nlohmann::json::object();
    for (std::size_t b = 1; b < generic.bodies.size(); ++b) {
      per_body[generic.bodies[b].name] = {factors[b][0], factors[b][1], factors[b][2]};
    }
    recorded["factors"] = per_body;
    trial.recorded_options["scale"] = recorded;
    summary["method"] = method;
    summary["factors"] = per_body;
    summary["total_mass_kg"] = p.model.total_mass_kg();
    summary["static_marker_rms_m"] = p.marker_rms_before_m;
    summary["markers_moved"] = p.markers_moved;
    summary["warnings"] = warnings;
    return summary;
  }

 private:
  // One row: each body's x, y and z factors.
  static Storage factors_table(const Model& m, const std::vector<Eigen::Vector3d>& f) {
    std::vector<std::string> labels;
    Eigen::MatrixXd row(1, 3 * (static_cast<Eigen::Index>(m.bodies.size()) - 1));
    for (std::size_t b = 1; b < m.bodies.size(); ++b)
      for (int k = 0; k < 3; ++k) {
        labels.push_back(m.bodies[b].name + "_" + "xyz"[k]);
        row(0, static_cast<Eigen::Index>(3 * (b - 1) + static_cast<std::size_t>(k))) = f[b][k];
      }
    Storage s = make_storage("Scale factors", labels, {0.0}, row, false);
    s.extra_header = {"Per body, along its x, y and z axes (dimensionless)."};
    return s;
  }

  // One row: each tracked marker's distance (m) from its measured place at the static pose, on the
  // scaled model before its markers were moved.
  static Storage static_errors_table(const Model& scaled, const MarkerTrial& st, const IkTaskSet& tasks,
                                     const std::optional<std::pair<double, double>>& range, const MarkerPlacement& p) {
    const MarkerTrial frame = average_static_frame(st, range);
    const IkTargets targets = make_ik_targets(scaled, frame, tasks, IkOptions{});
    KinematicsWorkspace<double> ws(scaled);
    forward_kinematics(scaled, p.static_pose.data(), ws);
    std::vector<std::string> labels;
    std::vector<double> values;
    for (const auto& t : targets.markers) {
      const Eigen::Vector3d x = frame.position_m(0, t.trial_marker);
      if (!x.allFinite()) continue;
      labels.push_back(scaled.markers[t.model_marker].name);
      values.push_back((marker_position(scaled, t.model_marker, ws) - x).norm());
    }
    Storage s = make_storage("Static marker errors", labels, {p.time_s},
                             Eigen::Map<const Eigen::MatrixXd>(values.data(), 1, static_cast<Eigen::Index>(values.size())), false);
    s.extra_header = {"Each marker's distance (m) from its measured place at the static pose, before the markers were placed."};
    return s;
  }
};

}  // namespace

const Stage& scale_stage() {
  static const ScaleStage s;
  return s;
}

}  // namespace cpgait::services
