#include "cpgait/capture/analyze_setup.h"

#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

AnalyzeSetup read_analyze_setup(const std::string& path) {
  const auto d = xml::Document::load_file(path);
  const pugi::xml_node tool = d.tool("AnalyzeTool");
  AnalyzeSetup s;
  s.name = tool.attribute("name").value();
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  s.model_file = d.text(tool, "model_file");
  const std::string force_sets = d.text(tool, "force_set_files");
  for (auto f : text::split_ws(force_sets)) s.force_set_files.emplace_back(f);
  s.replace_force_set = d.boolean(tool, "replace_force_set", false);
  s.results_directory = d.text(tool, "results_directory", std::string(1, '.'));
  if (s.results_directory.empty()) s.results_directory.push_back('.');
  s.coordinates_file = d.text(tool, "coordinates_file");
  s.external_loads_file = d.text(tool, "external_loads_file");
  s.lowpass_cutoff_hz = d.number(tool, "lowpass_cutoff_frequency_for_coordinates", -1);
  if (tool.child("initial_time") || tool.child("final_time"))
    s.time_range_s = std::make_pair(d.number(tool, "initial_time", 0.0), d.number(tool, "final_time", 1e30));
  s.states_file = d.text(tool, "states_file");
  s.solve_for_equilibrium = d.boolean(tool, "solve_for_equilibrium_for_auxiliary_states", false);
  if (s.coordinates_file.empty() && s.states_file.empty())
    throw InputError(path, d.line_of(tool), "coordinates_file", "the AnalyzeTool setup names no coordinates file or states file");
  for (const auto& a : tool.child("AnalysisSet").child("objects").children()) {
    if (a.type() != pugi::node_element) continue;
    const std::string kind = a.name();
    if (!d.boolean(a, "on", true)) continue;
    if (kind == "InverseDynamics") {
      s.has_inverse_dynamics = true;
      if (d.boolean(a, "use_model_force_set", true))
        s.warnings.push_back(path + ":" + std::to_string(d.line_of(a)) +
                             ": InverseDynamics: use_model_force_set is true, but only the model's passive coordinate forces are "
                             "subtracted, not its muscles' and actuators'");
      continue;
    }
    if (kind == "MuscleAnalysis") {
      s.has_muscle_analysis = true;
      s.muscle_analysis_name = a.attribute("name").value();
      s.muscle_analysis_step_interval = static_cast<int>(d.number(a, "step_interval", 1));
      if (s.muscle_analysis_step_interval < 1) d.fail(a.child("step_interval"), "step_interval must be at least 1");
      const std::string muscles = d.text(a, "muscle_list"), coords = d.text(a, "moment_arm_coordinate_list");
      for (auto m : text::split_ws(muscles))
        if (m != "all") s.muscle_list.emplace_back(m);
      for (auto c : text::split_ws(coords)) s.moment_arm_coordinates.emplace_back(c);
      continue;
    }
    if (kind != "StaticOptimization") {
      s.warnings.push_back(path + ":" + std::to_string(d.line_of(a)) + ": analysis <" + kind + "> is not supported; it is not run");
      continue;
    }
    s.has_static_optimization = true;
    s.step_interval = static_cast<int>(d.number(a, "step_interval", 1));
    if (s.step_interval < 1) d.fail(a.child("step_interval"), "step_interval must be at least 1");
    s.activation_exponent = d.number(a, "activation_exponent", 2.0);
    if (!(s.activation_exponent >= 2.0))
      d.fail(a.child("activation_exponent"), "activation_exponent must be at least 2 (cpgait's solver supports p >= 2)");
    s.use_muscle_physiology = d.boolean(a, "use_muscle_physiology", true);
    s.use_model_force_set = d.boolean(a, "use_model_force_set", true);
    if (a.child("start_time") || a.child("end_time"))
      s.time_range_s = std::make_pair(d.number(a, "start_time", s.time_range_s ? s.time_range_s->first : 0.0),
                                      d.number(a, "end_time", s.time_range_s ? s.time_range_s->second : 1e30));
  }
  return s;
}

}  // namespace cpgait
