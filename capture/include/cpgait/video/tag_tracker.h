#pragma once
// Detection over a video in two passes. A fast pass over the whole frame (quads found on a decimated
// image; the payload is still decoded at full resolution) finds the large tags, which say where the
// subject is. A full-resolution pass then runs only over the region holding this frame's and the
// last few frames' tags, where the small, foreshortened or blurred ones (feet in swing) are. The
// result is close to full-resolution detection at a fraction of its cost.
#include <deque>
#include <opencv2/core.hpp>
#include <vector>

#include "cpgait/video/tag_detector.h"

namespace cpgait::video {

struct TagTrackerOptions {
  bool region_pass = true;       // off: the fast pass alone
  int memory_frames = 5;         // earlier frames whose tags widen the region
  double region_margin = 0.6;    // the region grows by this fraction of its size on each side...
  int region_margin_px = 24;     // ...plus this many pixels
  // The region spans the image's full height: a walking subject is upright, and the large tags the
  // fast pass finds (trunk, thighs) say where the feet are horizontally but not how far below.
  bool full_height = true;
};

class TagTracker {
 public:
  // `detector` configures the fast pass; the region pass is the same with quad_decimate = 1.
  TagTracker(const TagDetectorOptions& detector, const TagTrackerOptions& options = {});
  std::vector<TagDetection> detect(const cv::Mat& frame);
  double region_fraction() const { return frames_ ? region_area_ / frames_ : 0; }  // mean share of the image searched finely

 private:
  TagDetector fast_;
  TagDetector fine_;
  TagTrackerOptions options_;
  std::deque<cv::Rect2d> recent_;  // per earlier frame: the bounding box of its tags
  double region_area_ = 0;
  long frames_ = 0;
};

}  // namespace cpgait::video
