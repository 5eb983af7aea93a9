#include "cpgait/capture/id_setup.h"

#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/xml_document.h"

namespace cpgait {

IdSetup read_id_setup(const std::string& path) {
  const auto d = xml::Document::load_file(path);
  const pugi::xml_node tool = d.tool("InverseDynamicsTool");
  IdSetup s;
  s.name = tool.attribute("name").value();
  s.setup_dir = std::filesystem::absolute(path).parent_path().string();
  s.model_file = d.text(tool, "model_file");
  s.coordinates_file = d.text(tool, "coordinates_file");
  s.external_loads_file = d.text(tool, "external_loads_file");
  s.results_directory = d.text(tool, "results_directory", std::string(1, '.'));
  if (s.results_directory.empty()) s.results_directory.push_back('.');
  s.output_gen_force_file = d.text(tool, "output_gen_force_file");
  s.lowpass_cutoff_hz = d.number(tool, "lowpass_cutoff_frequency_for_coordinates", -1);
  s.time_range_s = d.time_range(tool);
  if (s.coordinates_file.empty())
    throw InputError(path, d.line_of(tool), "coordinates_file", "the ID setup names no coordinates file");
  return s;
}

}  // namespace cpgait
