#pragma once
// OpenSim ExternalLoads XML (the 20302 format and the current one): which columns of a ground
// reaction data file act on which body, and in which frames forces and points are expressed.
#include <string>
#include <vector>

namespace cpgait {

struct ExternalForceSpec {
  std::string name;
  std::string applied_to_body;
  std::string force_expressed_in_body = "ground";
  std::string point_expressed_in_body = "ground";
  std::string force_identifier;   // column prefix: <id>x, <id>y, <id>z
  std::string point_identifier;   // empty: applied at the body origin
  std::string torque_identifier;  // empty: no free torque
  int line = 0;                   // where it is defined, for messages
};

struct ExternalLoadsSpec {
  std::string name;
  std::string file;       // the XML it was read from
  std::string setup_dir;  // folder that relative paths are resolved against
  std::string datafile;   // as written
  std::string kinematics_file;
  double kinematics_cutoff_hz = -1;
  std::vector<ExternalForceSpec> forces;  // enabled ones only
};

ExternalLoadsSpec read_external_loads(const std::string& path);
// The same over an uploaded document; `name` is used in messages and relative paths are left as written.
ExternalLoadsSpec parse_external_loads(std::string content, const std::string& name);

}  // namespace cpgait
