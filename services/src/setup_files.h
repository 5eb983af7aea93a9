#pragma once
// Shared by the subcommands that read OpenSim setups: where the files a setup names are, and how
// warnings reach the user.
#include <string>
#include <vector>

#include "cpgait/model/osim_reader.h"

namespace cpgait::services {

// A file named by a setup: relative to the setup's folder, as OpenSim resolves it. OpenSim's
// published pipelines keep their models in OutputReference/ beside the setup, so that is tried
// next. Empty stays empty; a missing file throws InputError naming the setup and field.
std::string resolve_setup_file(const std::string& setup_dir, const std::string& name, const std::string& setup_path,
                               const char* field);

// What the user may change about a setup on run-tool's command line.
struct ToolOverrides {
  std::string results;  // write results here instead of the setup's results_directory (empty: the setup's)
  std::string model;    // use this model instead of the setup's model_file (empty: the setup's)
  std::string generic_model;  // scale the model's muscle lengths from this generic model (empty: as they are)
  std::string bounds = "clamped";  // IK coordinate bounds: clamped, all, none

  std::string results_dir(const std::string& setup_dir, const std::string& results_directory) const;
  // The model to use: the override, else the setup's model_file resolved as above; a setup that
  // names none is an InputError.
  std::string model_file(const std::string& setup_dir, const std::string& model_file, const std::string& setup_path) const;
};

void print_warnings(const std::vector<std::string>& warnings);

// A model for the muscle-driven subcommands (so, cmc, forward, gait): read, its warnings printed, its
// muscle lengths scaled from the generic model when one is named (scale_muscle_parameters.h) - else a
// warning when they look unscaled.
OsimReadResult read_muscle_model(const std::string& model, const std::string& generic_model);

}  // namespace cpgait::services
