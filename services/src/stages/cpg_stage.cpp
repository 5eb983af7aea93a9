// The CPG: a Matsuoka network fitted to the muscles' activity over the gait cycles of one foot: static
// optimization's activations, or CMC's excitations when the options' activation is cmc.
#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/activation/static_optimization.h"
#include "cpgait/kinematics/gait_events.h"
#include "products.h"
#include "stage.h"
#include "output_files.h"

namespace cpgait::services {
namespace {

struct CpgStageOptions {
  int pairs = 2;
  int pattern_units = 2;
  std::string foot;  // empty: calcn_r, else foot_r

  static const OptionFields<CpgStageOptions>& fields() {
    static const OptionFields<CpgStageOptions> f =
        OptionFields<CpgStageOptions>(
            "Fitted to the cycle-averaged SO activations (or CMC excitations) over one foot's gait cycles: heel strikes from the GRF's first "
            "vertical force (ground_force_vy), else from kinematics (Zeni 2008).")
            .integer("pairs", &CpgStageOptions::pairs, 1, 6, "rhythm oscillator pairs")
            .integer("pattern_units", &CpgStageOptions::pattern_units, 0, 2, "pattern-layer neurons per active muscle (0: muscles read the rhythm layer)")
            .text("foot", &CpgStageOptions::foot,
                  "the body whose heel strikes delimit the cycles (kinematic detection); absent: calcn_r, else foot_r");
    return f;
  }
};

// Heel strikes from the GRF's first vertical force, else from the foot's kinematics.
std::vector<double> heel_strikes(const StageContext& trial, const IkProduct& ik, const std::string& foot_option, std::string& source) {
  std::vector<double> strikes;
  if (!trial.inputs.grf.empty()) {
    const Storage grf = parse_storage(trial.inputs.grf, trial.inputs.grf_name);
    for (int c = 1; c < grf.num_columns() && strikes.empty(); ++c)
      if (grf.labels[static_cast<std::size_t>(c)] == "ground_force_vy") {
        strikes = contact_onsets(grf.time(), grf.data.col(c));
        source = "GRF ground_force_vy (20 N threshold)";
      }
  }
  if (strikes.size() < 2) {
    const std::string foot = !foot_option.empty() ? foot_option : trial.model.body_index("calcn_r") >= 0 ? "calcn_r" : "foot_r";
    strikes = heel_strikes_zeni(trial.model, ik.time_s, ik.q, foot);
    source = "kinematics (Zeni 2008), " + foot;
  }
  return strikes;
}

class CpgStage final : public StageWithOptions<CpgStageOptions> {
 public:
  std::string name() const override { return "cpg"; }
  std::string description() const override { return "CPG fit: a Matsuoka network that regenerates the activations"; }
  std::vector<std::string> needs() const override { return {"activation"}; }
  std::vector<std::string> writes() const override { return {"_cpg.json", "_cpg_target.sto", "_cpg_fitted.sto", "_cpg_neurons.sto"}; }
  std::vector<std::string> tables() const override { return {"_cpg_target.sto", "_cpg_fitted.sto", "_cpg_neurons.sto"}; }

 protected:
  nlohmann::json execute(StageContext& trial, const CpgStageOptions& o) const override {
    const IkProduct& ik = *trial.products.find<IkProduct>();
    // The muscles' activity over time: CMC's excitations (each window's, held over it) or SO's activations.
    const auto* cmc = trial.products.find<ComputedMuscleControlResult>();
    const auto* so = trial.products.find<StaticOptimizationResult>();
    if (!cmc && !so) return {{"not_fitted", "no activation stage ran (so or cmc)"}};
    const int nm = static_cast<int>(trial.model.muscles.size());
    const std::vector<double>& activity_time = cmc ? cmc->control_time_s : so->time_s;
    const Eigen::MatrixXd activity = cmc ? Eigen::MatrixXd(cmc->controls.leftCols(nm)) : Eigen::MatrixXd(so->controls.leftCols(nm));
    const std::vector<std::string> names = cmc ? cmc->muscle_names : std::vector<std::string>(so->names.begin(), so->names.begin() + nm);
    const char* activity_name = cmc ? "cycle-averaged CMC excitations" : "cycle-averaged SO activations";
    std::string source;
    const std::vector<double> strikes = heel_strikes(trial, ik, o.foot, source);
    int cycles = 0;
    const double cycle_s = mean_cycle_duration(activity_time, strikes, &cycles);
    nlohmann::json summary = {{"heel_strikes_s", strikes}, {"heel_strike_source", source}, {"cycles", cycles},
                              {"fitted_to", cmc ? "cmc excitations" : "so activations"}};
    if (cycles == 0 || nm == 0) {
      // Not an error of the trial: IK, ID and SO stand; the stage says why it fitted nothing.
      summary["not_fitted"] = nm == 0 ? "the model has no muscles" : "no full gait cycle (two heel strikes of one foot) inside the trial";
      return summary;
    }
    CpgFitOptions fo;
    fo.pairs = o.pairs;
    fo.pattern_units = o.pattern_units;
    const Eigen::MatrixXd cycle = cycle_average(activity_time, activity, strikes, fo.phase_samples);
    const CpgFitResult fit = fit_cpg(cycle, cycle_s, names, fo);
    trial.write_text(json_text(fit.model.to_json(), 2) + "\n", "_cpg.json");
    std::vector<double> phase_time;
    for (int k = 0; k < cycle.rows(); ++k) phase_time.push_back(cycle_s * k / static_cast<double>(cycle.rows()));
    trial.write(make_storage(activity_name, names, phase_time, fit.target, false), "_cpg_target.sto");
    trial.write(make_storage("CPG excitations, fitted", names, phase_time, fit.fitted, false), "_cpg_fitted.sto");
    const CpgRun run = run_cpg(fit.model, cycle_s, cycle_s / static_cast<double>(cycle.rows()));
    std::vector<std::string> neurons;
    const int rhythm = 2 * fo.pairs;
    for (int i = 0; i < fit.model.network.size(); ++i)
      neurons.push_back(i < rhythm ? "rhythm" + std::to_string(i) : "pattern" + std::to_string(i - rhythm));
    trial.write(make_storage("CPG neuron outputs over one cycle", neurons, run.time_s, run.neurons, false), "_cpg_neurons.sto");
    nlohmann::json r2 = nlohmann::json::object();
    for (std::size_t k = 0; k < names.size(); ++k) r2[names[k]] = fit.summary.r_squared[static_cast<Eigen::Index>(k)];
    summary["cycle_s"] = cycle_s;
    summary["mean_r_squared_active"] = fit.summary.mean_r_squared_active;
    summary["active_muscles"] = fit.summary.active_muscles;
    summary["neurons"] = fit.model.network.size();
    summary["r_squared"] = r2;
    trial.products.put(FittedCpg{fit.model, strikes});
    return summary;
  }
};

}  // namespace

const Stage& cpg_stage() {
  static const CpgStage stage;
  return stage;
}

}  // namespace cpgait::services
