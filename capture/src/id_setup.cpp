#include "cpgait/capture/id_setup.h"

#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

IdSetup read_id_setup(const std::string& path) {
  const auto d = xml::Document::load_file(path);
  auto tool = d.doc().document_element();
  if (std::string(tool.name()) == "OpenSimDocument") tool = tool.child("InverseDynamicsTool");
  if (!tool || std::string(tool.name()) != "InverseDynamicsTool")
    throw InputError(path, 1, "InverseDynamicsTool", "not an OpenSim ID setup: no <InverseDynamicsTool>");
  IdSetup s;
  s.name = tool.attribute("name").value();
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  s.model_file = d.text(tool, "model_file");
  s.coordinates_file = d.text(tool, "coordinates_file");
  s.external_loads_file = d.text(tool, "external_loads_file");
  if (s.external_loads_file == "Unassigned") s.external_loads_file.clear();
  s.results_directory = d.text(tool, "results_directory", std::string(1, '.'));
  if (s.results_directory.empty()) s.results_directory.push_back('.');
  s.output_gen_force_file = d.text(tool, "output_gen_force_file");
  s.lowpass_cutoff_hz = d.number(tool, "lowpass_cutoff_frequency_for_coordinates", -1);
  if (const auto tr = tool.child("time_range")) {
    const auto v = d.numbers_of(tr);
    if (v.size() != 2 || !(v[0] <= v[1])) d.fail(tr, "expected two increasing times in seconds");
    s.time_range_s = std::make_pair(v[0], v[1]);
  }
  if (s.coordinates_file.empty())
    throw InputError(path, d.line_of(tool), "coordinates_file", "the ID setup names no coordinates file");
  return s;
}

}  // namespace cpgait
