// Static optimization: muscle activations that produce the joint moments, frame by frame.
#include "cpgait/activation/static_optimization.h"
#include "cpgait/muscles/scale_muscle_parameters.h"
#include "default_actuators.h"
#include "products.h"
#include "stage.h"

namespace cpgait::services {
namespace {

struct SoStageOptions {
  double activation_exponent = 2.0;
  bool use_muscle_physiology = true;
  double lowpass_cutoff_hz = 6.0;

  static const OptionFields<SoStageOptions>& fields() {
    static const OptionFields<SoStageOptions> f =
        OptionFields<SoStageOptions>("Minimum sum of activations to the power p, frame by frame, as OpenSim's StaticOptimization.")
            .number("activation_exponent", &SoStageOptions::activation_exponent, "", "the exponent p", NumberRange{2.0, {}})
            .boolean("use_muscle_physiology", &SoStageOptions::use_muscle_physiology,
                     "muscle forces from force-length-velocity (OpenSim's default); false: activation times max isometric force")
            .number("lowpass_cutoff_hz", &SoStageOptions::lowpass_cutoff_hz, "Hz",
                    "low-pass cutoff of the coordinates, as in ID; negative: no filtering");
    return f;
  }
};

class SoStage final : public StageWithOptions<SoStageOptions> {
 public:
  std::string name() const override { return "so"; }
  std::string description() const override { return "static optimization: muscle activations and forces"; }
  std::vector<std::string> needs() const override { return {"ik"}; }
  std::vector<std::string> writes() const override { return {"_StaticOptimization_activation.sto", "_StaticOptimization_force.sto"}; }
  std::vector<std::string> tables() const override { return writes(); }
  std::string activation_method() const override { return "so"; }

 protected:
  nlohmann::json execute(StageContext& trial, const SoStageOptions& o) const override {
    StaticOptimizationOptions so;
    so.activation_exponent = o.activation_exponent;
    so.use_muscle_physiology = o.use_muscle_physiology;
    so.lowpass_cutoff_hz = o.lowpass_cutoff_hz;
    const ResolvedActuators actuators(trial.model, default_actuators(trial.model));
    StaticOptimizationResult r =
        static_optimization(trial.model, trial.products.find<IkProduct>()->coordinates, trial.loads.get(), actuators, so, trial.progress);
    trial.write(static_optimization_activation_table(r), "_StaticOptimization_activation.sto");
    trial.write(static_optimization_force_table(r), "_StaticOptimization_force.sto");
    std::vector<std::string> warnings = r.summary.warnings;
    if (std::string w = unscaled_muscles_warning(trial.model); !w.empty()) warnings.push_back(std::move(w));
    nlohmann::json summary = {{"frames", r.summary.frames},
                              {"frames_per_second", r.summary.frames_per_second()},
                              {"max_equality_violation", r.summary.max_equality_violation},
                              {"frames_not_converged", r.summary.frames_not_converged},
                              {"warnings", warnings}};
    trial.products.put(std::move(r));
    return summary;
  }
};

}  // namespace

const Stage& so_stage() {
  static const SoStage stage;
  return stage;
}

}  // namespace cpgait::services
