#pragma once
// Tuning the reproduced gait's controller to walk without residual actuators: CMA-ES (cma_es.h) over
// the joint reflex's gains and the CPG's amplitude, each candidate one simulation of the gait
// (reproduce_gait, no residuals, reflex targets from the trial's cycle at the CPG's phase), scored by
//   (horizon - time walked) / horizon * fall_weight + tracking_weight * mean rotation RMS (rad)
//   + effort_weight * mean squared excitation,
// the falls first, then the deviation from the trial's cycle, then effort. The simulations run in
// parallel; the starting controller (the CPG's, else the defaults) is evaluated first, so the result
// is never worse than it. The result goes into the CPG (CpgModel::controller, its amplitude), whose
// JSON then replays it.
#include <string>

#include "cpgait/gait/reproduced_gait.h"

namespace cpgait {

struct GaitTuningOptions {
  int evaluations = 160;        // simulations CMA-ES may run (default 160)
  double horizon_s = 5.0;       // simulated time per candidate, s (default 5)
  double fall_weight = 10.0;    // cost of falling at once (default 10)
  double tracking_weight = 1.0; // cost per rad of mean rotation tracking RMS (default 1)
  double effort_weight = 0.1;   // cost per unit of mean squared excitation (default 0.1)
  int num_threads = 0;          // simulations in parallel; 0: every core
  unsigned long long seed = 1;
};

struct GaitTuningSummary {
  int evaluations = 0;
  double seconds = 0;
  double start_cost = 0, cost = 0;
  double start_walked_s = 0, walked_s = 0;  // time walked over the horizon before falling (= horizon: did not fall)
  std::string BriefReport() const;
};

struct GaitTuningResult {
  CpgModel cpg;  // the input CPG with the tuned controller and amplitude
  GaitTuningSummary summary;
};

// `options`: the gait's other settings (start, feet, tendons...); its duration, residuals, reference
// and reflex gains are the tuner's.
GaitTuningResult tune_gait_controller(const Model& model, const CpgModel& cpg, const Storage& reference_coordinates,
                                      const ContactSet& contacts, const ReproducedGaitOptions& options,
                                      const GaitTuningOptions& tuning = {}, Progress* progress = nullptr);

}  // namespace cpgait
