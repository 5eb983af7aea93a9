// Computed muscle control: muscle excitations that make the muscle-driven model track the IK
// kinematics, as the seed method estimates muscle activity. Runs instead of static optimization when
// the options' "activation" is "cmc".
#include "cpgait/activation/computed_muscle_control.h"

#include <algorithm>
#include <optional>

#include "cpgait/capture/input_error.h"
#include "default_actuators.h"
#include "products.h"
#include "stage.h"

namespace cpgait::services {
namespace {

struct CmcStageOptions {
  double window_s = 0.01;
  double kp = 100;
  double kv = 20;
  bool compliant_tendons = true;
  double lowpass_cutoff_hz = 6.0;

  static const OptionFields<CmcStageOptions>& fields() {
    static const OptionFields<CmcStageOptions> f =
        OptionFields<CmcStageOptions>(
            "OpenSim's CMC with its fast target, with the measured GRF when given. Without the trial's CMC files it tracks "
            "every unlocked coordinate of the IK (a CMC_Joint task each, weight 1) with residual actuators on the root joint's "
            "coordinates and reserves on the others, all of optimal force 1 (as static optimization's).")
            .number("window_s", &CmcStageOptions::window_s, "s", "CMC time window (OpenSim's cmc_time_window)", NumberRange{0.001, 0.1})
            .number("kp", &CmcStageOptions::kp, "1/s^2", "position gain of every derived task (a task file's own gains win)", NumberRange{0.0, 10000.0})
            .number("kv", &CmcStageOptions::kv, "1/s", "velocity gain of every derived task", NumberRange{0.0, 1000.0})
            .boolean("compliant_tendons", &CmcStageOptions::compliant_tendons,
                     "compliant tendons with fibre-length states (OpenSim's muscles); false: rigid tendons")
            .number("lowpass_cutoff_hz", &CmcStageOptions::lowpass_cutoff_hz, "Hz",
                    "low-pass cutoff of the tracked coordinates; negative: no filtering");
    return f;
  }
};

class CmcStage final : public StageWithOptions<CmcStageOptions> {
 public:
  std::string name() const override { return "cmc"; }
  std::string description() const override { return "computed muscle control: muscle excitations that track the IK"; }
  std::vector<std::string> needs() const override { return {"ik"}; }
  std::vector<std::string> writes() const override {
    return {"_cmc_controls.sto", "_cmc_states.sto", "_cmc_pErr.sto", "_cmc_Actuation_force.sto", "_cmc_avgResiduals.txt"};
  }
  std::vector<std::string> tables() const override {
    return {"_cmc_controls.sto", "_cmc_states.sto", "_cmc_pErr.sto", "_cmc_Actuation_force.sto"};
  }
  std::string activation_method() const override { return "cmc"; }

 protected:
  // Uploaded OpenSim files are read before anything runs, so that a bad one is refused at once.
  void check(const StageContext& trial, const CmcStageOptions& o) const override { (void)inputs(trial, o); }

  nlohmann::json execute(StageContext& trial, const CmcStageOptions& o) const override {
    const Model& model = trial.model;
    if (model.muscles.empty()) return {{"not_run", "the model has no muscles"}};
    const Inputs files = inputs(trial, o);
    ComputedMuscleControlOptions co;
    co.window_s = o.window_s;
    co.compliant_tendons = o.compliant_tendons;
    co.lowpass_cutoff_hz = o.lowpass_cutoff_hz;
    co.time_range_s = trial.time_range_s;
    const ResolvedActuators actuators(model, files.actuators);
    ComputedMuscleControlResult r =
        computed_muscle_control(model, trial.products.find<IkProduct>()->coordinates, trial.loads.get(), nullptr, actuators, files.tasks,
                                files.constraints ? &*files.constraints : nullptr, co, trial.progress);
    trial.write(cmc_controls_table(r), "_cmc_controls.sto");
    trial.write(cmc_states_table(r), "_cmc_states.sto");
    trial.write(cmc_position_error_table(r), "_cmc_pErr.sto");
    trial.write(cmc_actuation_force_table(r), "_cmc_Actuation_force.sto");
    trial.write_text(cmc_average_residuals_text(r), "_cmc_avgResiduals.txt");
    const Eigen::VectorXd rms = r.position_error_rms();
    nlohmann::json errors = nlohmann::json::object();
    for (int c = 0; c < model.num_coordinates(); ++c)
      errors[model.coordinates[c].name] = rms[c] * (model.coordinates[c].is_angle() ? 180.0 / M_PI : 1000.0);
    nlohmann::json residuals = nlohmann::json::object();
    for (const auto& [name, mean] : r.average_residuals()) residuals[name] = mean;
    nlohmann::json summary = {{"tasks", files.tasks_from},
                              {"actuators", files.actuators_from},
                              {"windows", r.summary.windows},
                              {"windows_infeasible", r.summary.windows_infeasible},
                              {"simulated_s", r.summary.simulated_s},
                              {"real_time_factor", r.summary.real_time_factor()},
                              {"external_forces", r.summary.external_forces},
                              {"tracking_error_rms_deg_or_mm", errors},
                              {"average_residuals", residuals},
                              {"warnings", r.summary.warnings}};
    if (files.constraints) summary["constraints"] = trial.inputs.cmc_constraints_name;
    trial.products.put(std::move(r));
    return summary;
  }

 private:
  struct Inputs {
    std::vector<CmcJointTask> tasks;
    std::vector<ActuatorSpec> actuators;
    std::optional<ControlSetSpec> constraints;
    std::string tasks_from, actuators_from;
  };

  // The uploaded task set, actuators (added to the model's own, as OpenSim's force_set_files) and
  // constraints; without files, a task per unlocked coordinate and weak residuals and reserves.
  static Inputs inputs(const StageContext& trial, const CmcStageOptions& o) {
    const TrialInputs& in = trial.inputs;
    const Model& model = trial.model;
    Inputs f;
    if (!in.cmc_tasks.empty()) {
      f.tasks = parse_cmc_tasks(in.cmc_tasks, in.cmc_tasks_name);
      f.tasks_from = in.cmc_tasks_name;
    } else {
      for (const Coordinate& c : model.coordinates) {
        if (c.locked) continue;
        CmcJointTask t;
        t.name = t.coordinate = c.name;
        t.kp = o.kp;
        t.kv = o.kv;
        f.tasks.push_back(t);
      }
      f.tasks_from = "every unlocked coordinate";
    }
    if (!in.cmc_actuators.empty()) {
      f.actuators = read_actuators(in.model_path);
      for (ActuatorSpec& a : parse_actuators(in.cmc_actuators, in.cmc_actuators_name))
        if (std::none_of(f.actuators.begin(), f.actuators.end(), [&](const ActuatorSpec& b) { return b.name == a.name; }))
          f.actuators.push_back(std::move(a));
      f.actuators_from = "the model's and " + in.cmc_actuators_name;
      (void)ResolvedActuators(model, f.actuators);  // an unknown coordinate or body names its file and line
    } else {
      f.actuators = default_actuators(model);
      f.actuators_from = "weak residuals and reserves";
    }
    if (!in.cmc_constraints.empty()) f.constraints = parse_control_set(in.cmc_constraints, in.cmc_constraints_name);
    for (const CmcJointTask& t : f.tasks)
      if (t.on && model.coordinate_index(t.coordinate) < 0)
        throw InputError(t.file, t.line, "coordinate", "task '" + t.name + "' tracks '" + t.coordinate + "', which is not in the model");
    return f;
  }
};

}  // namespace

const Stage& cmc_stage() {
  static const CmcStage stage;
  return stage;
}

}  // namespace cpgait::services
