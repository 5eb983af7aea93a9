#pragma once
// Which AprilTags are stuck on which body: id -> body, printed size and the tag's pose on the body.
// Every tag gives four virtual markers, its corners, named `tag<id>_<k>` unless the set names them.
// Tag frame (AprilTag's): origin at the centre, x to the right of the printed pattern, y down, z into
// the surface; corner k is at tag_corners_in_tag_frame(size)[k], the order the detector reports.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>


namespace cpgait::video {

struct TagMount {
  int id = 0;
  std::string body;
  double size_m = 0;  // edge of the square whose corners are detected (the black border's outer edge)
  Eigen::Vector3d position_in_body_m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation_body_from_tag = Eigen::Matrix3d::Identity();
  std::array<std::string, 4> corner_markers;
  std::string center_marker;  // optional: a marker at the tag's centre (the corners' mean)

  Eigen::Vector3d corner_in_body_m(int k) const;
};

struct TagSet {
  std::string family = "tag36h11";
  std::vector<TagMount> tags;

  const TagMount* find(int id) const;
  // 4 corners per tag, in tag order, then the centre markers of the tags that name one.
  std::vector<std::string> marker_names() const;
};

std::array<Eigen::Vector3d, 4> tag_corners_in_tag_frame(double size_m);

// JSON "cpgait.tagset/1": {"family": "tag36h11", "tags": [{"id", "body", "size_m", "position_m": [3],
// "rotation_body_from_tag": [9 row-major] or "orientation_body_xyz_deg": [3], "corner_markers": [4],
// "center_marker": "name"}]}.
TagSet read_tag_set(const std::string& path);
TagSet parse_tag_set_json(const std::string& text, const std::string& name);
std::string format_tag_set_json(const TagSet& set);

// The tag corners as an OpenSim MarkerSet document (4.x), so the captured TRC runs through IK in
// cpgait (`ik --marker-set`) or in OpenSim with the same model.
std::string format_marker_set_xml(const TagSet& set);

}  // namespace cpgait::video
