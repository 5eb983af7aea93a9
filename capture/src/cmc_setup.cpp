#include "cpgait/capture/cmc_setup.h"

#include <algorithm>
#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

namespace {

pugi::xml_node first_element_named(const pugi::xml_node& root, std::initializer_list<const char*> names) {
  for (const char* n : names) {
    if (std::string(root.name()) == n) return root;
    if (auto c = root.child(n)) return c;
  }
  return {};
}

void read_tool_common(const xml::Document& d, const pugi::xml_node& tool, std::string& name, std::string& model_file,
                      std::vector<std::string>& force_sets, bool& replace, std::string& results, double& t0, double& t1,
                      std::string& loads) {
  name = tool.attribute("name").value();
  model_file = d.text(tool, "model_file");
  const std::string files = d.text(tool, "force_set_files");  // split_ws returns views into it
  for (auto f : text::split_ws(files)) force_sets.emplace_back(f);
  replace = d.boolean(tool, "replace_force_set", false);
  results = d.text(tool, "results_directory");
  if (results.empty()) results.push_back('.');  // (not `= "."`: GCC 12 warns falsely with -Wrestrict)
  t0 = d.number(tool, "initial_time", 0.0, true);
  t1 = d.number(tool, "final_time", 0.0, true);
  if (!(t1 > t0)) d.fail(tool.child("final_time"), "final_time must be after initial_time");
  loads = d.text(tool, "external_loads_file");
}

}  // namespace

namespace {

std::vector<CmcJointTask> cmc_tasks_of(const xml::Document& d) {
  pugi::xml_node root = d.doc().document_element();
  if (std::string(root.name()) == "OpenSimDocument") root = root.first_child();
  const pugi::xml_node set = first_element_named(root, {"CMC_TaskSet", "rdCMC_TaskSet"});
  if (!set) d.fail(root, "expected a <CMC_TaskSet> (or <rdCMC_TaskSet>)");
  std::vector<CmcJointTask> tasks;
  for (const auto& t : set.child("objects").children()) {
    if (t.type() != pugi::node_element) continue;
    const std::string kind = t.name();
    if (kind != "CMC_Joint" && kind != "rdCMC_Joint")
      d.fail(t, "task type " + kind + " is not supported (cpgait's CMC tracks coordinates: CMC_Joint)");
    CmcJointTask task;
    task.name = t.attribute("name").value();
    task.coordinate = d.text(t, "coordinate", task.name);
    task.on = d.boolean(t, "on", true);
    auto first = [&](const char* key, double fallback) {
      if (!t.child(key)) return fallback;
      const auto v = d.numbers(t, key);
      if (v.empty()) d.fail(t.child(key), std::string(key) + " needs a number");
      return v[0];
    };
    task.kp = first("kp", 100);
    task.kv = first("kv", 20);
    task.ka = first("ka", 1);
    task.weight = first("weight", 1);
    if (t.child("active")) {
      const std::string active = d.text(t, "active");
      const auto words = text::split_ws(active);
      if (!words.empty() && words[0] == "false") task.on = false;
    }
    task.file = d.name();
    task.line = d.line_of(t);
    tasks.push_back(task);
  }
  if (tasks.empty()) d.fail(set, "the task set holds no tasks");
  return tasks;
}

}  // namespace

std::vector<CmcJointTask> read_cmc_tasks(const std::string& path) { return cmc_tasks_of(xml::Document::load_file(path)); }
std::vector<CmcJointTask> parse_cmc_tasks(const std::string& text, const std::string& name) {
  return cmc_tasks_of(xml::Document::load_string(text, name));
}

const ControlBounds* ControlSetSpec::find(const std::string& actuator) const {
  for (const auto& c : controls)
    if (c.name == actuator) return &c;
  return defaults ? &*defaults : nullptr;
}

namespace {

// OpenSim's ControlLinear::getControlValue over one node list: steps take the next node's value;
// otherwise linear between nodes and, with extrapolate, past the ends along the end segments.
double node_value(const std::vector<double>& t, const std::vector<double>& v, double at, bool use_steps, bool extrapolate) {
  const std::size_t n = t.size();
  if (n == 1) return v[0];
  auto line = [&](std::size_t i) { return t[i + 1] == t[i] ? v[i] : v[i] + (v[i + 1] - v[i]) * (at - t[i]) / (t[i + 1] - t[i]); };
  if (at < t[0]) return !use_steps && extrapolate ? line(0) : v[0];
  if (at >= t[n - 1]) return at > t[n - 1] && !use_steps && extrapolate ? line(n - 2) : v[n - 1];
  const std::size_t i = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), at) - t.begin()) - 1;
  if (use_steps) return at == t[i] ? v[i] : v[i + 1];
  return line(i);
}

}  // namespace

double ControlBounds::min_at(double t_s) const {
  return min_node_times_s.empty() ? min : node_value(min_node_times_s, min_node_values, t_s, use_steps, extrapolate);
}

double ControlBounds::max_at(double t_s) const {
  // As OpenSim: the max nodes count only with min nodes beside them.
  return min_node_times_s.empty() || max_node_times_s.empty() ? max : node_value(max_node_times_s, max_node_values, t_s, use_steps, extrapolate);
}

namespace {

ControlSetSpec control_set_of(const xml::Document& d) {
  pugi::xml_node root = d.doc().document_element();
  if (std::string(root.name()) == "OpenSimDocument") root = root.first_child();
  if (std::string(root.name()) != "ControlSet") d.fail(root, "expected a <ControlSet>");
  auto read = [&](const pugi::xml_node& c) {
    ControlBounds b;
    b.name = c.attribute("name").value();
    if (b.name.size() > 11 && b.name.compare(b.name.size() - 11, 11, ".excitation") == 0) b.name.resize(b.name.size() - 11);
    b.min = d.number(c, "default_min", 0.0);
    b.max = d.number(c, "default_max", 1.0);
    if (b.min > b.max) d.fail(c, "default_min is above default_max");
    b.use_steps = d.boolean(c, "use_steps", true);
    b.extrapolate = d.boolean(c, "extrapolate", true);
    auto nodes = [&](const char* tag, std::vector<double>& times, std::vector<double>& values) {
      for (const auto& n : c.child(tag).children("ControlLinearNode")) {
        times.push_back(d.number(n, "t", 0.0, true));
        values.push_back(d.number(n, "value", 0.0, true));
        if (times.size() > 1 && !(times.back() >= times[times.size() - 2])) d.fail(n, std::string(tag) + " times must not decrease");
      }
    };
    nodes("x_nodes", b.node_times_s, b.node_values);
    nodes("min_nodes", b.min_node_times_s, b.min_node_values);
    nodes("max_nodes", b.max_node_times_s, b.max_node_values);
    return b;
  };
  ControlSetSpec spec;
  if (auto def = root.child("defaults").child("ControlLinear")) spec.defaults = read(def);
  for (const auto& c : root.child("objects").children("ControlLinear")) spec.controls.push_back(read(c));
  return spec;
}

}  // namespace

ControlSetSpec read_control_set(const std::string& path) { return control_set_of(xml::Document::load_file(path)); }
ControlSetSpec parse_control_set(const std::string& text, const std::string& name) {
  return control_set_of(xml::Document::load_string(text, name));
}

CmcSetup read_cmc_setup(const std::string& path) {
  const auto d = xml::Document::load_file(path);
  const pugi::xml_node tool = d.tool("CMCTool");
  CmcSetup s;
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  read_tool_common(d, tool, s.name, s.model_file, s.force_set_files, s.replace_force_set, s.results_directory,
                   s.initial_time_s, s.final_time_s, s.external_loads_file);
  s.desired_kinematics_file = d.text(tool, "desired_kinematics_file");
  if (s.desired_kinematics_file.empty()) d.fail(tool, "the CMC setup names no desired_kinematics_file");
  s.task_set_file = d.text(tool, "task_set_file");
  if (s.task_set_file.empty()) d.fail(tool, "the CMC setup names no task_set_file");
  s.constraints_file = d.text(tool, "constraints_file");
  s.lowpass_cutoff_hz = d.number(tool, "lowpass_cutoff_frequency", -1);
  s.cmc_time_window_s = d.number(tool, "cmc_time_window", 0.01);
  if (!(s.cmc_time_window_s > 0 && s.cmc_time_window_s <= 0.5)) d.fail(tool.child("cmc_time_window"), "expected 0 < window <= 0.5 s");
  s.use_fast_target = d.boolean(tool, "use_fast_optimization_target", true);
  s.integrator_error_tolerance = d.number(tool, "integrator_error_tolerance", 1e-6);
  if (!d.text(tool, "desired_points_file").empty())
    d.fail(tool.child("desired_points_file"), "desired points (marker tracking) are not supported; give desired kinematics");
  return s;
}

ForwardSetup read_forward_setup(const std::string& path) {
  const auto d = xml::Document::load_file(path);
  const pugi::xml_node tool = d.tool("ForwardTool");
  ForwardSetup s;
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  read_tool_common(d, tool, s.name, s.model_file, s.force_set_files, s.replace_force_set, s.results_directory,
                   s.initial_time_s, s.final_time_s, s.external_loads_file);
  s.states_file = d.text(tool, "states_file");
  s.integrator_error_tolerance = d.number(tool, "integrator_error_tolerance", 1e-5);
  s.controls_file = d.text(tool, "controls_file");
  for (const auto& c : tool.child("ControllerSet").child("objects").children()) {
    const std::string kind = c.name();
    if (d.boolean(c, "isDisabled", false)) continue;
    if (kind == "ControlSetController" && s.controls_file.empty()) s.controls_file = d.text(c, "controls_file");
    if (kind == "CorrectionController") {
      s.correction_kp = d.number(c, "kp", 16);
      s.correction_kv = d.number(c, "kv", 8);
    }
  }
  if (s.controls_file.empty()) d.fail(tool, "the Forward setup names no controls_file");
  return s;
}

}  // namespace cpgait
