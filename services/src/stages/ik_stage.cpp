// Inverse kinematics: the model's markers fitted to the trial's, frame by frame (Ceres).
#include "cpgait/capture/ik_setup.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "products.h"
#include "ik_tasks_field.h"
#include "stage.h"

namespace cpgait::services {
namespace {

struct IkStageOptions {
  std::string bounds = "clamped";
  std::optional<nlohmann::json> tasks;

  IkOptions::Bounds solver_bounds() const {
    return bounds == "all" ? IkOptions::Bounds::kAllRanges : bounds == "none" ? IkOptions::Bounds::kNone : IkOptions::Bounds::kClampedOnly;
  }
  IkTaskSet task_set() const { return tasks ? parse_ik_tasks_json(tasks->dump(), "options (ik.tasks)") : IkTaskSet{}; }

  static const OptionFields<IkStageOptions>& fields() {
    static const OptionFields<IkStageOptions> f =
        OptionFields<IkStageOptions>("Ceres, frame by frame, as OpenSim's IK tool.")
            .choice("bounds", &IkStageOptions::bounds, {"clamped", "all", "none"},
                    "which coordinates are held to their range: those marked clamped (as OpenSim), all with a range, or none")
            .add(ik_tasks_field(&IkStageOptions::tasks,
                                "IK task weights: {\"markers\": {name: weight | {\"weight\", \"apply\"}}, \"coordinates\": {...}} "
                    "(capture/ik_setup.h; `cpgait run --ik-tasks` converts an OpenSim IKTaskSet); "
                    "absent: every marker, weight 1"));
    return f;
  }
};

class IkStage final : public StageWithOptions<IkStageOptions> {
 public:
  std::string name() const override { return "ik"; }
  std::string description() const override { return "inverse kinematics: coordinates from the markers"; }
  std::vector<std::string> writes() const override { return {"_ik.mot", "_ik_marker_errors.sto"}; }
  std::vector<std::string> tables() const override { return writes(); }

 protected:
  void check(const StageContext& trial, const IkStageOptions& o) const override {
    if (trial.inputs.has_footage()) return;  // the markers exist only after the capture stage
    IkOptions io;
    io.time_range_s = trial.time_range_s;
    make_ik_targets(trial.model, trial.markers, o.task_set(), io);
  }
  nlohmann::json execute(StageContext& trial, const IkStageOptions& o) const override {
    IkOptions io;
    io.bounds = o.solver_bounds();
    io.time_range_s = trial.time_range_s;
    const IkResult r = inverse_kinematics(trial.model, trial.markers, o.task_set(), io, nullptr, trial.progress);
    IkProduct product{ik_coordinates_table(trial.model, r), r.q, r.time_s};
    trial.write(product.coordinates, "_ik.mot");
    trial.write(ik_marker_errors_table(r), "_ik_marker_errors.sto");
    trial.products.put(std::move(product));
    return {{"frames", r.summary.frames},
            {"frames_per_second", r.summary.frames_per_second()},
            {"marker_rms_mean_m", r.summary.mean_marker_rms_m},
            {"marker_rms_max_m", r.summary.max_marker_rms_m},
            {"marker_error_max_m", r.summary.max_marker_error_m},
            {"frames_not_converged", r.summary.frames_not_converged},
            {"warnings", r.summary.warnings}};
  }
};

}  // namespace

const Stage& ik_stage() {
  static const IkStage stage;
  return stage;
}

}  // namespace cpgait::services
