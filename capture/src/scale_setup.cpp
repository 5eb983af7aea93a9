#include "cpgait/capture/scale_setup.h"

#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

namespace {

// The <objects> children named `kind` of a set child (OpenSim's Set layout).
std::vector<pugi::xml_node> set_objects(const pugi::xml_node& parent, const char* set, const char* kind) {
  std::vector<pugi::xml_node> out;
  for (const auto& n : parent.child(set).child("objects").children(kind)) out.push_back(n);
  return out;
}

ScaleSetup read_setup(const xml::Document& d, const std::string& path) {
  const pugi::xml_node tool = d.tool("ScaleTool");
  ScaleSetup s;
  s.name = tool.attribute("name").value();
  s.file = path;
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  s.mass_kg = d.number(tool, "mass", -1.0);
  // OpenSim's -1 means "not given" (masses then scale with the bodies' volumes).
  if (s.mass_kg != -1.0 && !(s.mass_kg > 0)) d.fail(tool.child("mass"), "the subject's mass must be positive (kg), or -1 for none");
  const pugi::xml_node maker = tool.child("GenericModelMaker");
  s.model_file = d.text(maker, "model_file");
  s.marker_set_file = d.text(maker, "marker_set_file");
  if (const pugi::xml_node placer = tool.child("MarkerPlacer")) {
    s.placer_apply = d.boolean(placer, "apply", true);
    s.placer_tasks = read_ik_task_set(d, placer.child("IKTaskSet"), s.setup_dir);
    s.placer_marker_file = d.text(placer, "marker_file");
    s.placer_time_range_s = d.time_range(placer);
    s.placer_output_model_file = d.text(placer, "output_model_file");
    s.placer_output_motion_file = d.text(placer, "output_motion_file");
    s.placer_output_marker_file = d.text(placer, "output_marker_file");
  }
  const pugi::xml_node scaler = tool.child("ModelScaler");
  if (!scaler) {
    s.scaler_apply = false;
    return s;
  }
  s.scaler_apply = d.boolean(scaler, "apply", true);
  const std::string order = d.text(scaler, "scaling_order", "measurements");
  for (auto w : text::split_ws(order)) {
    if (w != "measurements" && w != "manualScale")
      d.fail(scaler.child("scaling_order"), "expected 'measurements' or 'manualScale', found '" + std::string(w) + "'");
    s.scaling_order.emplace_back(w);
  }
  for (const auto& m : set_objects(scaler, "MeasurementSet", "Measurement")) {
    if (!d.boolean(m, "apply", true)) continue;
    ScaleMeasurement meas;
    meas.name = m.attribute("name").value();
    meas.line = d.line_of(m);
    for (const auto& p : set_objects(m, "MarkerPairSet", "MarkerPair")) {
      const std::string names = d.text(p, "markers");
      const auto w = text::split_ws(names);
      if (w.size() != 2) d.fail(p.child("markers") ? p.child("markers") : p, "a marker pair names two markers");
      meas.marker_pairs.emplace_back(std::string(w[0]), std::string(w[1]));
    }
    for (const auto& b : set_objects(m, "BodyScaleSet", "BodyScale")) {
      std::array<bool, 3> axes{false, false, false};
      const std::string text_axes = d.text(b, "axes", "X Y Z");
      for (auto a : text::split_ws(text_axes)) {
        if (a == "X" || a == "x") axes[0] = true;
        else if (a == "Y" || a == "y") axes[1] = true;
        else if (a == "Z" || a == "z") axes[2] = true;
        else d.fail(b.child("axes"), "axes are X, Y or Z, found '" + std::string(a) + "'");
      }
      meas.body_axes.emplace_back(b.attribute("name").value(), axes);
    }
    s.measurements.push_back(std::move(meas));
  }
  for (const auto& sc : set_objects(scaler, "ScaleSet", "Scale")) {
    if (!d.boolean(sc, "apply", true)) continue;
    const auto f = d.numbers(sc, "scales");
    if (f.size() != 3) d.fail(sc.child("scales") ? sc.child("scales") : sc, "a Scale has three factors");
    for (double v : f)
      if (!(v > 0)) d.fail(sc.child("scales"), "scale factors must be positive");
    s.manual_scales.push_back({d.text(sc, "segment"), {f[0], f[1], f[2]}});
  }
  s.marker_file = d.text(scaler, "marker_file");
  s.time_range_s = d.time_range(scaler);
  s.preserve_mass_distribution = d.boolean(scaler, "preserve_mass_distribution", false);
  s.output_model_file = d.text(scaler, "output_model_file");
  s.output_scale_file = d.text(scaler, "output_scale_file");
  return s;
}

}  // namespace

ScaleSetup read_scale_setup(const std::string& path) { return read_setup(xml::Document::load_file(path), path); }

ScaleSetup parse_scale_setup(std::string content, const std::string& name) {
  return read_setup(xml::Document::load_string(std::move(content), name), name);
}

}  // namespace cpgait
