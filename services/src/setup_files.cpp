#include "setup_files.h"

#include <cstdio>
#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/muscles/scale_muscle_parameters.h"

namespace cpgait::services {
namespace fs = std::filesystem;

std::string resolve_setup_file(const std::string& setup_dir, const std::string& name, const std::string& setup_path,
                               const char* field) {
  if (name.empty()) return name;
  const fs::path p(name);
  if (p.is_absolute() && fs::exists(p)) return p.string();
  for (const fs::path& candidate : {fs::path(setup_dir) / p, fs::path(setup_dir) / "OutputReference" / p})
    if (fs::exists(candidate)) return candidate.lexically_normal().string();
  throw InputError(setup_path, 0, field, "file '" + name + "' not found beside the setup");
}

std::string ToolOverrides::results_dir(const std::string& setup_dir, const std::string& results_directory) const {
  return !results.empty() ? results : (fs::path(setup_dir) / results_directory).string();
}

std::string ToolOverrides::model_file(const std::string& setup_dir, const std::string& model_file, const std::string& setup_path) const {
  if (!model.empty()) {
    if (!fs::exists(model)) throw InputError(model, 0, "--model", "file not found");
    return model;
  }
  const std::string path = resolve_setup_file(setup_dir, model_file, setup_path, "model_file");
  if (path.empty()) throw InputError(setup_path, 0, "model_file", "the setup names no model");
  return path;
}

void print_warnings(const std::vector<std::string>& warnings) {
  for (const auto& w : warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
}

OsimReadResult read_muscle_model(const std::string& model, const std::string& generic_model) {
  OsimReadResult r = read_osim(model);
  print_warnings(r.warnings);
  if (!generic_model.empty()) {
    MuscleScalingSummary ms;
    r.model = scale_muscle_parameters(r.model, read_osim(generic_model).model, &ms);
    std::fprintf(stderr, "muscles scaled from %s: %s\n", generic_model.c_str(), ms.BriefReport().c_str());
  } else if (const std::string w = unscaled_muscles_warning(r.model); !w.empty()) {
    print_warnings({w});
  }
  return r;
}

}  // namespace cpgait::services
