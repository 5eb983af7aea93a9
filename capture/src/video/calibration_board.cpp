#include "cpgait/video/calibration_board.h"

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/video/tag_family.h"
#include "cpgait/video/tag_set.h"

namespace cpgait::video {

const BoardTag* CalibrationBoard::find(int id) const {
  for (const BoardTag& t : tags)
    if (t.id == id) return &t;
  return nullptr;
}

Eigen::Vector3d CalibrationBoard::corner_in_board_m(const BoardTag& tag, int k) const {
  return tag.board_from_tag * tag_corners_in_tag_frame(tag_size_m)[static_cast<std::size_t>(k)];
}

CalibrationBoard make_aprilgrid(const AprilGridSpec& s) {
  CalibrationBoard b;
  b.family = s.family;
  b.tag_size_m = s.tag_size_m;
  const double pitch = s.tag_size_m * (1 + s.spacing);
  const double width = s.cols * s.tag_size_m + (s.cols - 1) * s.spacing * s.tag_size_m;
  b.board_from_face.push_back(Eigen::Isometry3d::Identity());
  if (s.double_sided) {
    Eigen::Isometry3d back = Eigen::Isometry3d::Identity();
    back.linear() = Eigen::Vector3d(-1, 1, -1).asDiagonal();
    back.translation() = Eigen::Vector3d(width, 0, s.thickness_m);
    b.board_from_face.push_back(back);
  }
  int id = s.first_id;
  for (std::size_t f = 0; f < b.board_from_face.size(); ++f)
    for (int r = 0; r < s.rows; ++r)
      for (int c = 0; c < s.cols; ++c) {
        Eigen::Isometry3d face_from_tag = Eigen::Isometry3d::Identity();
        face_from_tag.translation() = Eigen::Vector3d(c * pitch + s.tag_size_m / 2, r * pitch + s.tag_size_m / 2, 0);
        b.tags.push_back({id++, static_cast<int>(f), b.board_from_face[f] * face_from_tag});
      }
  return b;
}

AprilGridSpec parse_aprilgrid_spec(const std::string& text, const std::string& name) {
  const nlohmann::json j = parse_json_input(text, name);
  if (!j.is_object()) throw InputError(name, 0, "", "expected a JSON object describing the board");
  const std::string type = json_field_or<std::string>(j, "type", "aprilgrid", name, "");
  if (type != "aprilgrid") throw InputError(name, 0, "type", "unsupported board type '" + type + "' (expected aprilgrid)");
  AprilGridSpec s;
  s.family = json_field_or(j, "family", s.family, name, "");
  s.rows = json_field<int>(j, "rows", name, "");
  s.cols = json_field<int>(j, "cols", name, "");
  s.tag_size_m = json_field<double>(j, "tag_size_m", name, "");
  s.spacing = json_field_or(j, "spacing", s.spacing, name, "");
  s.first_id = json_field_or(j, "first_id", 0, name, "");
  s.double_sided = json_field_or(j, "double_sided", false, name, "");
  s.thickness_m = json_field_or(j, "thickness_m", s.thickness_m, name, "");
  if (s.rows < 1 || s.cols < 1 || s.rows * s.cols > 2000) throw InputError(name, 0, "rows", "rows and cols must be 1..2000 tags");
  if (!(s.tag_size_m > 0.005 && s.tag_size_m < 2)) throw InputError(name, 0, "tag_size_m", "tag size must be in metres (0.005 to 2)");
  if (!(s.spacing >= 0 && s.spacing < 5)) throw InputError(name, 0, "spacing", "spacing is a fraction of the tag size (0 to 5)");
  int codes = 0;
  try {
    codes = tag_family_info(s.family).num_codes;
  } catch (const std::invalid_argument& e) {
    throw InputError(name, 0, "family", e.what());
  }
  const int needed = s.first_id + s.rows * s.cols * (s.double_sided ? 2 : 1);
  if (s.first_id < 0 || needed > codes)
    throw InputError(name, 0, "first_id", "the board needs ids up to " + std::to_string(needed - 1) + " but " + s.family +
                                              " has " + std::to_string(codes));
  return s;
}

AprilGridSpec read_aprilgrid_spec(const std::string& path) { return parse_aprilgrid_spec(text::read_file(path), path); }

std::string format_aprilgrid_spec(const AprilGridSpec& s) {
  return nlohmann::json{{"type", "aprilgrid"},     {"family", s.family},         {"rows", s.rows},
                        {"cols", s.cols},          {"tag_size_m", s.tag_size_m}, {"spacing", s.spacing},
                        {"first_id", s.first_id},  {"double_sided", s.double_sided},
                        {"thickness_m", s.thickness_m}}
             .dump(2) +
         "\n";
}

}  // namespace cpgait::video
