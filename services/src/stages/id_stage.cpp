// Inverse dynamics: the generalized forces that produce the IK coordinates under the measured loads.
#include "cpgait/dynamics/inverse_dynamics.h"
#include "products.h"
#include "stage.h"

namespace cpgait::services {
namespace {

struct IdStageOptions {
  double lowpass_cutoff_hz = 6.0;

  static const OptionFields<IdStageOptions>& fields() {
    static const OptionFields<IdStageOptions> f =
        OptionFields<IdStageOptions>("Recursive Newton-Euler with the ground reaction forces, as OpenSim's ID tool.")
            .number("lowpass_cutoff_hz", &IdStageOptions::lowpass_cutoff_hz, "Hz",
                    "low-pass cutoff of the coordinates, OpenSim's Butterworth; negative: no filtering");
    return f;
  }
};

class IdStage final : public StageWithOptions<IdStageOptions> {
 public:
  std::string name() const override { return "id"; }
  std::string description() const override { return "inverse dynamics: joint moments and residual forces"; }
  std::vector<std::string> needs() const override { return {"ik"}; }
  std::vector<std::string> writes() const override { return {"_id.sto"}; }
  std::vector<std::string> tables() const override { return writes(); }

 protected:
  nlohmann::json execute(StageContext& trial, const IdStageOptions& o) const override {
    InverseDynamicsOptions io;
    io.lowpass_cutoff_hz = o.lowpass_cutoff_hz;
    const InverseDynamicsResult r =
        inverse_dynamics(trial.model, trial.products.find<IkProduct>()->coordinates, trial.loads.get(), io, trial.progress);
    trial.write(inverse_dynamics_table(trial.model, r), "_id.sto");
    return {{"frames", r.summary.frames},
            {"frames_per_second", r.summary.frames_per_second()},
            {"external_loads", trial.loads != nullptr},
            {"warnings", r.summary.warnings}};
  }
};

}  // namespace

const Stage& id_stage() {
  static const IdStage stage;
  return stage;
}

}  // namespace cpgait::services
