#include "cpgait/video/tag_family.h"

#include <stdexcept>

namespace cpgait::video {

// The two families' geometry and code counts, as the AprilTag library defines them (a test compares
// them with the library's): known without loading it.
TagFamilyInfo tag_family_info(const std::string& family) {
  if (family == "tag36h11") return {family, 10, 8, 587};
  if (family == "tagStandard41h12") return {family, 9, 5, 2115};
  throw std::invalid_argument("unknown tag family '" + family + "' (expected tag36h11 or tagStandard41h12)");
}

int tag_bitmap_border_offset_cells(const std::string& family) {
  const TagFamilyInfo info = tag_family_info(family);
  return (info.total_width - info.width_at_border) / 2 + 1;
}

}  // namespace cpgait::video
