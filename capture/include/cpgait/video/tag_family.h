#pragma once
// The AprilTag families cpgait reads: tag36h11 (the common default) and tagStandard41h12 (AprilTag 3's
// recommended family: more codes, smaller for the same data area).
#include <opencv2/core.hpp>
#include <string>

namespace cpgait::video {

struct TagFamilyInfo {
  std::string name;
  int total_width = 0;      // cells across the whole printed pattern
  int width_at_border = 0;  // cells across the square whose corners the detector reports
  int num_codes = 0;
};

// Throws std::invalid_argument naming the supported families for any other name.
TagFamilyInfo tag_family_info(const std::string& family);

// The tag's cells (0 black, 255 white) with one white cell of quiet zone around the pattern, so the
// detected corners sit at cells pad .. pad + width_at_border where pad = (total - border)/2 + 1.
cv::Mat tag_bitmap(const std::string& family, int id);
int tag_bitmap_border_offset_cells(const std::string& family);

}  // namespace cpgait::video
