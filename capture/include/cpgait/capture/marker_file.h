#pragma once
// Marker trajectories from a TRC or a C3D file, told apart by content (a C3D's second byte is 0x50),
// so every command and upload that takes a .trc takes a .c3d too.
#include <string>
#include <string_view>

#include "cpgait/capture/trc.h"

namespace cpgait {

// The lab's vertical axis in a C3D file. OpenSim's is Y: a Z-up file (Vicon, Qualisys, BTS and most
// labs) is turned -90 deg about X, (x, y, z) -> (x, z, -y), markers and (later) forces alike.
enum class C3dVertical { kZ, kY };

MarkerTrial parse_marker_file(std::string_view bytes, const std::string& name, C3dVertical c3d_vertical = C3dVertical::kZ);
MarkerTrial read_marker_file(const std::string& path, C3dVertical c3d_vertical = C3dVertical::kZ);

}  // namespace cpgait
