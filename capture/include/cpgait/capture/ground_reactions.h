#pragma once
// A C3D trial's force plates as OpenSim's ground reactions: a GRF table (.mot) with, per plate and
// foot, <id>ground_force_v{x,y,z} (N), <id>ground_force_p{x,y,z} (m) and <id>ground_torque_{x,y,z}
// (N m) at the analog rate, in OpenSim's frame (turned like the markers), and the ExternalLoads
// document that applies each to the foot that stood on the plate. A stance is assigned to the foot
// whose heel marker (a name holding HEE, FCC or CALC, its side from an R/L prefix or suffix) is
// nearest the centre of pressure over the stance, unless the options name the plate's foot.
#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/storage.h"

namespace cpgait {

struct GroundReactionOptions {
  double threshold_N = 20.0;  // vertical force below which a plate is unloaded. Default 20 N.
  std::map<int, char> plate_foot;  // plate number (1-based) -> 'r' or 'l': every stance on it. Default: by heel markers.
  std::string right_body = "calcn_r", left_body = "calcn_l";  // the bodies the loads act on (OpenSim's gait models')
  double min_stance_s = 0.02;  // a shorter loaded run is noise, not a stance. Default 20 ms.
  double lowpass_hz = 0;       // the plates' forces and moments low-passed before the COP (Hz); 0: as recorded. Default 0.
};

struct Stance {
  int plate = 0;
  char foot = '?';  // 'r', 'l', or '?' when neither a heel marker nor the options tell
  double begin_s = 0, end_s = 0;
  double peak_vertical_N = 0;
};

struct GroundReactions {
  Storage grf;  // OpenSim's GRF .mot columns, time from the trial's first frame as its TRC's
  std::vector<Stance> stances;
  // Per column group: the identifier prefix ("1_", "2r_", ...) and the body it acts on.
  std::vector<std::pair<std::string, std::string>> loads;
  bool negated_any = false;  // some plate's channels gave the force on the plate (negated)
  std::vector<std::string> warnings;
};

// `to_opensim`: the rotation applied to the markers (lab -> OpenSim's frame). Throws InputError for a
// damaged FORCE_PLATFORM group; a file without plates gives an empty table.
GroundReactions ground_reactions(const C3dFile& file, const Eigen::Matrix3d& to_opensim, const GroundReactionOptions& options = {});

// The ExternalLoads document for the table written as `datafile` (its file name).
std::string external_loads_document(const GroundReactions& g, const std::string& datafile);

}  // namespace cpgait
