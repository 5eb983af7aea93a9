#include "cpgait/video/tag_set.h"

#include <cstdio>
#include <set>

#include "cpgait/capture/body_xyz.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/video/tag_family.h"

namespace cpgait::video {

std::array<Eigen::Vector3d, 4> tag_corners_in_tag_frame(double s) {
  const double h = s / 2;
  return {Eigen::Vector3d(-h, h, 0), Eigen::Vector3d(h, h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(-h, -h, 0)};
}

Eigen::Vector3d TagMount::corner_in_body_m(int k) const {
  return rotation_body_from_tag * tag_corners_in_tag_frame(size_m)[static_cast<std::size_t>(k)] + position_in_body_m;
}

const TagMount* TagSet::find(int id) const {
  for (const TagMount& t : tags)
    if (t.id == id) return &t;
  return nullptr;
}

std::vector<std::string> TagSet::marker_names() const {
  std::vector<std::string> names;
  for (const TagMount& t : tags) names.insert(names.end(), t.corner_markers.begin(), t.corner_markers.end());
  for (const TagMount& t : tags)
    if (!t.center_marker.empty()) names.push_back(t.center_marker);
  return names;
}

TagSet parse_tag_set_json(const std::string& text, const std::string& name) {
  using nlohmann::json;
  const json j = parse_json_input(text, name);
  if (!j.is_object() || !j.contains("tags") || !j["tags"].is_array())
    throw InputError(name, 0, "tags", "expected an object with a \"tags\" array");
  TagSet set;
  set.family = json_field_or(j, "family", set.family, name, "");
  int num_codes = 0;
  try {
    num_codes = tag_family_info(set.family).num_codes;
  } catch (const std::invalid_argument& e) {
    throw InputError(name, 0, "family", e.what());
  }
  std::set<int> ids;
  std::set<std::string> markers;
  for (std::size_t i = 0; i < j["tags"].size(); ++i) {
    const json& t = j["tags"][i];
    const std::string at = "tags[" + std::to_string(i) + "]";
    TagMount m;
    m.id = json_field<int>(t, "id", name, at);
    if (m.id < 0 || m.id >= num_codes)
      throw InputError(name, 0, at + ".id", "not an id of " + set.family + " (0.." + std::to_string(num_codes - 1) + ")");
    if (!ids.insert(m.id).second) throw InputError(name, 0, at + ".id", "tag " + std::to_string(m.id) + " listed twice");
    m.body = json_field<std::string>(t, "body", name, at);
    m.size_m = json_field<double>(t, "size_m", name, at);
    if (!(m.size_m > 0.005 && m.size_m < 2))
      throw InputError(name, 0, at + ".size_m", "tag size must be in metres (0.005 to 2)");
    const auto p = json_field<std::vector<double>>(t, "position_m", name, at);
    if (p.size() != 3) throw InputError(name, 0, at + ".position_m", "expected 3 numbers");
    m.position_in_body_m = {p[0], p[1], p[2]};
    if (t.contains("rotation_body_from_tag")) {
      const auto r = json_field<std::vector<double>>(t, "rotation_body_from_tag", name, at);
      if (r.size() != 9) throw InputError(name, 0, at + ".rotation_body_from_tag", "expected 9 numbers, row-major");
      for (int k = 0; k < 9; ++k) m.rotation_body_from_tag(k / 3, k % 3) = r[static_cast<std::size_t>(k)];
      const double orth = (m.rotation_body_from_tag * m.rotation_body_from_tag.transpose() - Eigen::Matrix3d::Identity()).norm();
      if (orth > 1e-6 || m.rotation_body_from_tag.determinant() < 0)
        throw InputError(name, 0, at + ".rotation_body_from_tag", "not a rotation matrix");
    } else if (t.contains("orientation_body_xyz_deg")) {
      const auto a = json_field<std::vector<double>>(t, "orientation_body_xyz_deg", name, at);
      if (a.size() != 3) throw InputError(name, 0, at + ".orientation_body_xyz_deg", "expected 3 angles");
      m.rotation_body_from_tag = rotation_from_body_xyz(Eigen::Vector3d(a[0], a[1], a[2]) * (M_PI / 180));
    }
    for (int k = 0; k < 4; ++k) m.corner_markers[static_cast<std::size_t>(k)] = "tag" + std::to_string(m.id) + "_" + std::to_string(k);
    if (t.contains("corner_markers")) {
      const auto names = json_field<std::vector<std::string>>(t, "corner_markers", name, at);
      if (names.size() != 4) throw InputError(name, 0, at + ".corner_markers", "expected 4 marker names");
      for (int k = 0; k < 4; ++k) m.corner_markers[static_cast<std::size_t>(k)] = names[static_cast<std::size_t>(k)];
    }
    if (t.contains("center_marker")) {
      m.center_marker = json_field<std::string>(t, "center_marker", name, at);
      if (!markers.insert(m.center_marker).second)
        throw InputError(name, 0, at + ".center_marker", "marker name " + m.center_marker + " used twice");
    }
    for (const std::string& mk : m.corner_markers)
      if (!markers.insert(mk).second) throw InputError(name, 0, at + ".corner_markers", "marker name " + mk + " used twice");
    set.tags.push_back(m);
  }
  return set;
}

TagSet read_tag_set(const std::string& path) { return parse_tag_set_json(text::read_file(path), path); }

std::string format_tag_set_json(const TagSet& set) {
  using nlohmann::json;
  json tags = json::array();
  for (const TagMount& m : set.tags) {
    std::vector<double> r(9);
    for (int k = 0; k < 9; ++k) r[static_cast<std::size_t>(k)] = m.rotation_body_from_tag(k / 3, k % 3);
    tags.push_back({{"id", m.id},
                    {"body", m.body},
                    {"size_m", m.size_m},
                    {"position_m", {m.position_in_body_m.x(), m.position_in_body_m.y(), m.position_in_body_m.z()}},
                    {"rotation_body_from_tag", r},
                    {"corner_markers", m.corner_markers}});
    if (!m.center_marker.empty()) tags.back()["center_marker"] = m.center_marker;
  }
  return json{{"schema", "cpgait.tagset/1"}, {"family", set.family}, {"tags", tags}}.dump(2) + "\n";
}

std::string format_marker_set_xml(const TagSet& set) {
  std::string out = "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40000\">\n\t<MarkerSet name=\"tag_corners\">\n\t\t<objects>\n";
  char buf[512];
  auto marker = [&](const std::string& name, const std::string& body, const Eigen::Vector3d& p) {
    std::snprintf(buf, sizeof buf,
                  "\t\t\t<Marker name=\"%s\">\n\t\t\t\t<socket_parent_frame>/bodyset/%s</socket_parent_frame>\n"
                  "\t\t\t\t<location>%.9g %.9g %.9g</location>\n\t\t\t\t<fixed>false</fixed>\n\t\t\t</Marker>\n",
                  name.c_str(), body.c_str(), p.x(), p.y(), p.z());
    out += buf;
  };
  for (const TagMount& t : set.tags)
    for (int k = 0; k < 4; ++k) marker(t.corner_markers[static_cast<std::size_t>(k)], t.body, t.corner_in_body_m(k));
  for (const TagMount& t : set.tags)
    if (!t.center_marker.empty()) marker(t.center_marker, t.body, t.position_in_body_m);
  out += "\t\t</objects>\n\t\t<groups />\n\t</MarkerSet>\n</OpenSimDocument>\n";
  return out;
}

}  // namespace cpgait::video
