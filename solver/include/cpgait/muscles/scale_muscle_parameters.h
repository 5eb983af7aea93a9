#pragma once
// OpenSim's ScaleTool, for the muscles (Muscle::extendPostScale): once the bones and path points are
// scaled, each muscle's optimal fibre length and tendon slack length are multiplied by the ratio of
// its path length after scaling to before, both at the default pose, so that the muscle works at the
// same normalized fibre lengths as in the generic model. A model whose path points were scaled
// without this (opensim-models' subject01_simbody*.osim carry gait2392's generic muscle parameters on
// paths up to 17 % longer, which puts the hamstrings and rectus femoris at 1.4 optimal fibre lengths
// standing) gets it here from the generic model it was scaled from.
#include <string>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

struct MuscleScalingSummary {
  int muscles_scaled = 0;
  std::vector<std::string> not_in_generic;  // muscles left as they were
  double smallest_ratio = 1, largest_ratio = 1;
  std::string BriefReport() const;
};

// `scaled` with its muscles' optimal fibre and tendon slack lengths scaled as above; muscles are
// matched by name.
Model scale_muscle_parameters(const Model& scaled, const Model& generic, MuscleScalingSummary* summary = nullptr);

// Each muscle's rigid-tendon fibre length at the default pose, in optimal fibre lengths
// ((path - tendon slack) / optimal fibre length, pennation ignored): the check that shows a model
// whose muscles were not scaled with its bones.
std::vector<double> normalized_fiber_lengths_at_default_pose(const Model& model);
// A warning when several muscles (5 or more) sit beyond 1.3 optimal fibre lengths at the default pose,
// naming the worst; empty otherwise.
std::string unscaled_muscles_warning(const Model& model);

}  // namespace cpgait
