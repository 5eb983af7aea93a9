#pragma once
// Reads OpenSim .osim models (3.x and 4.x documents) into a Model. What the reader does not
// understand is reported in `warnings`, never dropped silently; what it cannot use throws
// InputError naming the file, line and element.
#include <string>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

struct OsimReadOptions {
  // A marker-set XML (<MarkerSet> or an OpenSimDocument holding one) whose markers replace the
  // model's markers of the same name and add the others.
  std::string marker_set_file;
  std::size_t max_bytes = std::size_t{256} << 20;
};

struct OsimReadResult {
  Model model;
  std::vector<std::string> warnings;
};

OsimReadResult read_osim(const std::string& path, const OsimReadOptions& options = {});
OsimReadResult parse_osim(std::string content, const std::string& name, const OsimReadOptions& options = {});

}  // namespace cpgait
