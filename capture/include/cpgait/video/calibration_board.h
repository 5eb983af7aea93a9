#pragma once
// Calibration boards made of AprilTags: an AprilGrid (rows x cols tags, gaps of `spacing` x tag size),
// optionally printed on both sides of a plate so cameras facing each other see it at once.
// Board frame = front face frame: origin at the grid's top-left outer corner, x along a row, y down
// the columns, z into the board. The back face carries the next rows x cols ids, laid out as seen from
// behind.
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace cpgait::video {

struct AprilGridSpec {
  std::string family = "tag36h11";
  int rows = 5;
  int cols = 6;
  double tag_size_m = 0.1;
  double spacing = 0.3;  // gap between tags as a fraction of the tag size (Kalibr's convention)
  int first_id = 0;
  bool double_sided = false;
  double thickness_m = 0.005;
};

struct BoardTag {
  int id = 0;
  int face = 0;
  Eigen::Isometry3d board_from_tag = Eigen::Isometry3d::Identity();
};

struct CalibrationBoard {
  std::string family;
  double tag_size_m = 0;
  std::vector<Eigen::Isometry3d> board_from_face;  // every face's tags lie in its z = 0 plane
  std::vector<BoardTag> tags;

  const BoardTag* find(int id) const;
  Eigen::Vector3d corner_in_board_m(const BoardTag& tag, int k) const;
};

CalibrationBoard make_aprilgrid(const AprilGridSpec& spec);

// JSON {"type": "aprilgrid", "family", "rows", "cols", "tag_size_m", "spacing", "first_id",
// "double_sided", "thickness_m"}; throws InputError.
AprilGridSpec read_aprilgrid_spec(const std::string& path);
AprilGridSpec parse_aprilgrid_spec(const std::string& text, const std::string& name);
std::string format_aprilgrid_spec(const AprilGridSpec& spec);

}  // namespace cpgait::video
