#pragma once
// OpenSim's subject01 walking trial as the pipeline takes it (model, markers, GRF, loads), for the
// benchmarks that run pipeline stages; false when ../shared is absent.
#include <filesystem>
#include <string>

#include "cpgait/capture/text_lines.h"
#include "trial_inputs.h"

namespace cpgait::bench {

inline bool subject01_trial(services::TrialInputs& in) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) return false;
  in.name = "subject01_walk1";
  in.model_path = base + "OutputReference/subject01_simbody.osim";
  in.markers = text::read_file(base + "subject01_walk1.trc"), in.markers_name = "subject01_walk1.trc";
  in.grf = text::read_file(base + "subject01_walk1_grf.mot"), in.grf_name = "subject01_walk1_grf.mot";
  in.loads = text::read_file(base + "subject01_walk1_grf.xml"), in.loads_name = "subject01_walk1_grf.xml";
  return true;
}

}  // namespace cpgait::bench
