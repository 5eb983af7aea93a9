#pragma once
// How far a walking controller stands from falling: its walk again with each feedback gain (the joint
// reflex's kp and kv, the trunk's kp and kv, foot placement's d and v across and along the way; where
// the controller uses them, the swing hip's world share and the stance hold's d and v) scaled in turn
// by a factor and by its inverse, the others as they are. A controller whose changed walks still last
// has margin. At subject01's knob 0.8 every tuned controller fell within 3-7 s when any one gain moved
// by a fifth, where knob 1's kept some walks (measured: docs/gait-tuning.md).
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cpgait/gait/reproduced_gait.h"

namespace cpgait {

struct GainMarginOptions {
  double factor = 0.8;  // each gain walked at factor and at 1 / factor times its value, 0 < factor < 1 (default 0.8: 0.8 and 1.25)
  int num_threads = 0;  // walks in parallel; 0: every core
};

struct GainMarginWalk {
  std::string gain;     // reflex_kp, reflex_kv, trunk_kp, trunk_kv, lateral_d, lateral_v, sagittal_d or sagittal_v
  double scale = 1;
  double walked_s = 0;  // time walked before falling; the walk's duration where it did not fall
  bool fell = false;
};

struct GainMarginSummary {
  double factor = 0;                  // GainMarginOptions::factor
  std::vector<GainMarginWalk> walks;  // two per gain (factor, then 1 / factor), in the order above
  int still_walking = 0;              // walks that did not fall
  double median_walked_s = 0;
  std::string BriefReport() const;
  nlohmann::json to_json() const;  // factor, still_walking, median_walked_s and the walks (gain, scale, walked_s, fell)
};

// `options`: the walk as it is taken, its controller's gains in it (with_controller). Each changed walk
// is reproduce_gait with one gain scaled; a gain of 0 (that feedback off) is walked as it is.
GainMarginSummary gain_margin(const Model& model, const CpgModel& cpg, const Storage& reference, const ContactSet& contacts,
                              const ReproducedGaitOptions& options, const GainMarginOptions& margin = {});

}  // namespace cpgait
