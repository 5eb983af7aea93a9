#pragma once
// OpenSim's ModelScaler scale factors: per body, from the setup's measurements (the static trial's
// marker-pair distances over the model's, in its default pose) and manual scales, applied in the
// setup's scaling_order. Bodies no measurement or manual scale names keep 1.
#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/scale_setup.h"
#include "cpgait/capture/trc.h"
#include "cpgait/model/model.h"

namespace cpgait {

struct ModelScaleFactors {
  std::vector<Eigen::Vector3d> body;                      // per model body, ground included
  std::vector<std::pair<std::string, double>> measured;  // each measurement's factor, as OpenSim prints them
  std::vector<std::string> warnings;  // bodies the setup names that the model lacks
};

// A measured factor outside this range means wrong units or markers, not a subject.
inline constexpr double kMinScaleFactor = 0.5, kMaxScaleFactor = 2.0;

// The static trial is needed when the order names "measurements"; its time range is the setup's
// (OpenSim's: from the last frame at or before its start to the first at or after its end).
// Throws InputError naming the setup, the measurement's line and what is wrong when measurements are
// asked for without a static trial, when a measurement's marker is missing from the model or the
// trial (OpenSim only warns and leaves the bodies unscaled), or when a factor is outside
// kMinScaleFactor..kMaxScaleFactor.
ModelScaleFactors model_scale_factors(const Model& model, const ScaleSetup& setup, const MarkerTrial* static_trial);

// OpenSim's ScaleSet document (the ScaleTool's output_scale_file): one <Scale> per body, ground first.
std::string scale_set_document(const Model& model, const std::vector<Eigen::Vector3d>& factors);

}  // namespace cpgait
