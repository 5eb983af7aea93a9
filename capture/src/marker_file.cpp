#include "cpgait/capture/marker_file.h"

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait {

MarkerTrial parse_marker_file(std::string_view bytes, const std::string& name, C3dVertical c3d_vertical) {
  if (!looks_like_c3d(bytes)) return parse_trc(bytes, name);
  MarkerTrial trial = parse_c3d(bytes, name).markers;
  if (c3d_vertical == C3dVertical::kZ) {
    Eigen::Matrix3d to_y_up;
    to_y_up << 1, 0, 0, 0, 0, 1, 0, -1, 0;
    trial.positions_m = to_y_up * trial.positions_m;
  }
  return trial;
}

MarkerTrial read_marker_file(const std::string& path, C3dVertical c3d_vertical) {
  return parse_marker_file(text::read_file(path), path, c3d_vertical);
}

}  // namespace cpgait
