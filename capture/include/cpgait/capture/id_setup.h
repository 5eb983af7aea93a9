#pragma once
// OpenSim's InverseDynamicsTool setup. Paths are as written; `setup_dir` is what they are relative to.
#include <optional>
#include <string>
#include <utility>

namespace cpgait {

struct IdSetup {
  std::string name;
  std::string setup_dir;
  std::string model_file;
  std::string coordinates_file;
  std::string external_loads_file;
  std::string results_directory = ".";
  std::string output_gen_force_file;
  std::optional<std::pair<double, double>> time_range_s;
  double lowpass_cutoff_hz = -1;  // negative: no filtering (OpenSim's default)
};

IdSetup read_id_setup(const std::string& path);

}  // namespace cpgait
