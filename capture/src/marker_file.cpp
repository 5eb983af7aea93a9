#include "cpgait/capture/marker_file.h"

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/force_plates.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait {

Eigen::Matrix3d c3d_to_opensim(const C3dFile& file, C3dVertical vertical) {
  const int axis = vertical == C3dVertical::kZ ? 2 : vertical == C3dVertical::kY ? 1 : c3d_vertical_axis(file);
  Eigen::Matrix3d r;
  if (axis == 2) r << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  else if (axis == 0) r << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  else r.setIdentity();
  return r;
}

MarkerTrial parse_marker_file(std::string_view bytes, const std::string& name, C3dVertical c3d_vertical) {
  if (!looks_like_c3d(bytes)) return parse_trc(bytes, name);
  const C3dFile file = parse_c3d(bytes, name);
  MarkerTrial trial = file.markers;
  trial.positions_m = c3d_to_opensim(file, c3d_vertical) * trial.positions_m;
  return trial;
}

MarkerTrial read_marker_file(const std::string& path, C3dVertical c3d_vertical) {
  return parse_marker_file(text::read_file(path), path, c3d_vertical);
}

}  // namespace cpgait
