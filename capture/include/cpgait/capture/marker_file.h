#pragma once
// Marker trajectories from a TRC or a C3D file, told apart by content (a C3D's second byte is 0x50),
// so every command and upload that takes a .trc takes a .c3d too.
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/trc.h"

namespace cpgait {

// The lab's vertical axis in a C3D file. OpenSim's is Y: a Z-up file (Vicon, Qualisys and most labs)
// is turned -90 deg about X, (x, y, z) -> (x, z, -y), an X-up one +90 deg about Z; markers and forces
// alike. kAuto reads it from the file (c3d_vertical_axis: the force plates' normal, else
// POINT:Y_SCREEN, else Z): BTS's files are Y-up.
enum class C3dVertical { kAuto, kZ, kY };

// The rotation from the file's lab frame to OpenSim's.
Eigen::Matrix3d c3d_to_opensim(const C3dFile& file, C3dVertical vertical);

MarkerTrial parse_marker_file(std::string_view bytes, const std::string& name, C3dVertical c3d_vertical = C3dVertical::kAuto);
MarkerTrial read_marker_file(const std::string& path, C3dVertical c3d_vertical = C3dVertical::kAuto);

}  // namespace cpgait
