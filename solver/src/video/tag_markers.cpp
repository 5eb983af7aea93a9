#include "cpgait/video/tag_markers.h"

#include "cpgait/capture/input_error.h"

namespace cpgait::video {

Model with_tag_markers(const Model& model, const TagSet& set, const std::string& set_name) {
  Model out = model;
  for (std::size_t i = 0; i < set.tags.size(); ++i) {
    const TagMount& t = set.tags[i];
    const int body = model.body_index(t.body);
    if (body < 0)
      throw InputError(set_name, 0, "tags[" + std::to_string(i) + "].body", "model " + model.name + " has no body " + t.body);
    auto add = [&](const Marker& mk) {
      const int existing = out.marker_index(mk.name);
      if (existing >= 0) {
        out.markers[static_cast<std::size_t>(existing)] = mk;
      } else {
        out.markers.push_back(mk);
      }
    };
    for (int k = 0; k < 4; ++k) add(Marker{t.corner_markers[static_cast<std::size_t>(k)], body, t.corner_in_body_m(k), false});
    if (!t.center_marker.empty()) add(Marker{t.center_marker, body, t.position_in_body_m, false});
  }
  return out;
}

}  // namespace cpgait::video
