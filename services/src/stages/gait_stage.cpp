// The reproduced gait: the fitted CPG drives the muscles on contact spheres fitted to the trial's feet.
#include <algorithm>

#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/gait/tune_gait_controller.h"
#include "products.h"
#include "stage.h"
#include "output_files.h"

namespace cpgait::services {
namespace {

struct GaitStageOptions {
  std::optional<double> duration_s;
  bool residuals = true;
  bool phase_reference = false;
  int tune_evaluations = 0;
  double tune_horizon_s = 5.0;
  int tune_rounds = 1;

  static const OptionFields<GaitStageOptions>& fields() {
    static const OptionFields<GaitStageOptions> f =
        OptionFields<GaitStageOptions>(
            "Begins at the first heel strike, or earlier when the trial would end first; needs the cpg stage's fit.")
            .optional_number("duration_s", &GaitStageOptions::duration_s, "s",
                             "simulated time; absent: with residuals two gait cycles, or what the trial has; without, the trial's length "
                             "and at least 10 s", NumberRange{0.0, 30.0, true})
            .boolean("residuals", &GaitStageOptions::residuals,
                     "pelvis residual actuators hold the rotations and soft springs the translations; false: the model walks on its own")
            .boolean("phase_reference", &GaitStageOptions::phase_reference,
                     "the joint reflexes track the trial's cycle average at the CPG's phase (read from its rhythm neurons), not the trial at the simulation's time")
            .integer("tune_evaluations", &GaitStageOptions::tune_evaluations, 0, 5000,
                     "tune the controller to walk without residuals first: CMA-ES over the reflex and balance gains and the CPG's amplitude, this "
                     "many simulations in parallel (0: no tuning); the tuned CPG is written to _cpg_tuned.json and drives the gait")
            .number("tune_horizon_s", &GaitStageOptions::tune_horizon_s, "s", "simulated time per tuning candidate",
                    NumberRange{0.5, 30.0, true})
            .integer("tune_rounds", &GaitStageOptions::tune_rounds, 1, 10,
                     "CMA-ES restarts, each from the last best, their horizons rising evenly to tune_horizon_s");
    return f;
  }
};

class GaitStage final : public StageWithOptions<GaitStageOptions> {
 public:
  std::string name() const override { return "gait"; }
  std::string description() const override { return "reproduced gait: the CPG-driven muscles walk the model on contact spheres"; }
  std::vector<std::string> needs() const override { return {"cpg"}; }
  std::vector<std::string> writes() const override {
    return {"_gait.mot", "_gait_residuals.sto", "_gait_contact_forces.sto", "_gait.json", "_cpg_tuned.json (when tuned)"};
  }
  std::vector<std::string> tables() const override { return {"_gait.mot", "_gait_residuals.sto"}; }

 protected:
  nlohmann::json execute(StageContext& trial, const GaitStageOptions& o) const override {
    const IkProduct& ik = *trial.products.find<IkProduct>();
    const FittedCpg* cpg = trial.products.find<FittedCpg>();
    if (!cpg) return {{"not_run", "no CPG was fitted in this run (see the cpg stage)"}};
    const Model& model = trial.model;
    ContactSet feet = default_foot_contacts(model);
    if (feet.spheres.empty()) return {{"not_run", "the model has no calcn_/toes_ or foot_ bodies for contact spheres"}};
    // The simulation begins at the first heel strike whose phase lies in the trial, or earlier when
    // the trial would end first.
    const double cycle_s = cpg->model.cycle_s;
    double start = -1;
    for (double s : cpg->heel_strikes_s)
      if (!ik.time_s.empty() && s + cpg->model.phase_at_start * cycle_s >= ik.time_s.front()) {
        start = s;
        break;
      }
    const double available = ik.time_s.empty() ? 0 : ik.time_s.back() - ik.time_s.front();
    if (start < 0 || available < 0.5 * cycle_s)
      return {{"not_run", "the trial is shorter than half a gait cycle, or has no usable heel strike"}};

    const Storage reference = make_storage("ik", coordinate_names(model), ik.time_s, ik.q, false);
    const FootSphereFit fit = fit_foot_spheres_to_trial(model, feet, ik.time_s, ik.q);
    ReproducedGaitOptions go;
    go.start_time_s = start;
    go.duration_s = o.duration_s ? *o.duration_s : std::min(2 * cycle_s, available);
    go.pelvis_residuals = o.residuals;
    go.phase_indexed_reference = o.phase_reference;
    // A CPG fitted to CMC's excitations drives compliant-tendon muscles, as CMC's did (the seed method).
    go.compliant_tendons = trial.products.find<ComputedMuscleControlResult>() != nullptr;
    CpgModel driving = cpg->model;
    nlohmann::json tuning;
    if (o.tune_evaluations > 0) {
      GaitTuningOptions to;
      to.evaluations = o.tune_evaluations;
      to.horizon_s = o.tune_horizon_s;
      to.rounds = o.tune_rounds;
      const GaitTuningResult tuned = tune_gait_controller(model, cpg->model, reference, feet, go, to, trial.progress);
      driving = tuned.cpg;
      trial.write_text(json_text(driving.to_json(), 2) + "\n", "_cpg_tuned.json");
      tuning = {{"simulations", tuned.summary.evaluations}, {"seconds", tuned.summary.seconds},
                {"cost", {tuned.summary.start_cost, tuned.summary.cost}}, {"walked_s", {tuned.summary.start_walked_s, tuned.summary.walked_s}},
                {"horizon_s", to.horizon_s}, {"controller", driving.controller->to_json()}, {"amplitude", driving.amplitude}};
    }
    if (driving.controller) go = with_controller(*driving.controller, go);  // a tuned CPG walks as it was tuned
    // Walking on its own, as long as the trial and at least 10 s (issue 22); held by residuals, which
    // need the trial's pelvis, what the trial has.
    if (!o.duration_s && !go.pelvis_residuals) go.duration_s = std::max(10.0, available);
    const ReproducedGaitResult g = reproduce_gait(model, driving, reference, feet, go, trial.progress);
    trial.write(reproduced_gait_motion_table(model, g), "_gait.mot");
    trial.write(reproduced_gait_residual_table(g), "_gait_residuals.sto");
    trial.write(reproduced_gait_contact_table(g), "_gait_contact_forces.sto");
    nlohmann::json summary = reproduced_gait_metrics(model, g);
    summary["compliant_tendons"] = go.compliant_tendons;
    summary["pelvis_residuals"] = go.pelvis_residuals;
    if (!tuning.is_null()) summary["tuning"] = tuning;
    nlohmann::json radius = nlohmann::json::object();
    for (std::size_t s = 0; s < feet.spheres.size(); ++s) radius[feet.spheres[s].name] = fit.radius_change_m[s] * 1000;
    summary["foot_fit"] = {{"depth_mm", fit.depth_m * 1000}, {"radius_change_mm", radius}, {"warnings", fit.warnings}};
    summary["belt_velocity_m_s"] = {feet.ground_velocity_m_s.x(), feet.ground_velocity_m_s.y(), feet.ground_velocity_m_s.z()};
    trial.write_text(json_text(summary, 2) + "\n", "_gait.json");
    return summary;
  }
};

}  // namespace

const Stage& gait_stage() {
  static const GaitStage stage;
  return stage;
}

}  // namespace cpgait::services
