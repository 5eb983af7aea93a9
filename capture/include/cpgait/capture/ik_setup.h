#pragma once
// OpenSim's InverseKinematicsTool setup and IK task sets (IKMarkerTask / IKCoordinateTask), from the
// setup XML, a standalone IKTaskSet XML, or the JSON equivalent:
//   {"markers": {"R.ASIS": 10, "Top.Head": {"weight": 0.1, "apply": true}},
//    "coordinates": {"subtalar_angle_r": {"weight": 1000, "value_type": "default_value"}}}
#include <optional>
#include <string>
#include <vector>

namespace pugi {
class xml_node;
}
namespace cpgait::xml {
class Document;
}

namespace cpgait {

struct IkMarkerTask {
  std::string name;
  double weight = 1.0;
  bool apply = true;
};

struct IkCoordinateTask {
  enum class ValueType { kDefaultValue, kManualValue, kFromFile };
  std::string name;
  double weight = 1.0;
  bool apply = true;
  ValueType value_type = ValueType::kDefaultValue;
  double value = 0.0;  // with kManualValue; in the coordinate's internal unit (rad or m)
};

struct IkTaskSet {
  std::vector<IkMarkerTask> markers;
  std::vector<IkCoordinateTask> coordinates;
  bool empty() const { return markers.empty() && coordinates.empty(); }
};

// Fields as in the setup file; relative paths are left as written, `setup_dir` is where they are
// relative to (OpenSim resolves them against the setup file's folder).
struct IkSetup {
  std::string name;
  std::string setup_dir;
  std::string model_file;
  std::string marker_file;
  std::string coordinate_file;
  std::string results_directory = ".";
  std::string output_motion_file;
  std::optional<std::pair<double, double>> time_range_s;
  bool report_errors = true;
  double accuracy = 1e-5;
  double constraint_weight = 20;
  IkTaskSet tasks;
};

IkSetup read_ik_setup(const std::string& path);

// An <IKTaskSet> element inside another setup (the ScaleTool's MarkerPlacer), or the file its
// `file` attribute names relative to base_dir.
IkTaskSet read_ik_task_set(const xml::Document& d, const pugi::xml_node& set, const std::string& base_dir);
// An IKTaskSet XML (root <IKTaskSet> or inside <OpenSimDocument>) or a .json task file.
IkTaskSet read_ik_tasks(const std::string& path);
IkTaskSet parse_ik_tasks_json(const std::string& content, const std::string& name);
// The JSON equivalent of a task set (parse_ik_tasks_json reads it back unchanged).
std::string ik_tasks_json(const IkTaskSet& tasks);

}  // namespace cpgait
