#include "cpgait/video/tag_tracker.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace cpgait::video {

namespace {
TagDetectorOptions full_resolution(TagDetectorOptions o) {
  o.quad_decimate = 1.0f;
  return o;
}
cv::Rect2d bounding_box(const std::vector<TagDetection>& found) {
  if (found.empty()) return {};
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const TagDetection& d : found)
    for (const auto& c : d.corners_px) {
      x0 = std::min(x0, c.x());
      y0 = std::min(y0, c.y());
      x1 = std::max(x1, c.x());
      y1 = std::max(y1, c.y());
    }
  return {x0, y0, x1 - x0, y1 - y0};
}
}  // namespace

TagTracker::TagTracker(const TagDetectorOptions& detector, const TagTrackerOptions& options)
    : fast_(detector), fine_(full_resolution(detector)), options_(options) {}

std::vector<TagDetection> TagTracker::detect(const cv::Mat& image) {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = image;
  }
  ++frames_;
  std::vector<TagDetection> found = fast_.detect(gray);
  if (!options_.region_pass || fast_.options().quad_decimate <= 1.0f) return found;
  cv::Rect2d region = bounding_box(found);
  for (const cv::Rect2d& r : recent_) region = region.empty() ? r : (r.empty() ? region : (region | r));
  recent_.push_back(bounding_box(found));
  while (static_cast<int>(recent_.size()) > options_.memory_frames) recent_.pop_front();
  if (region.empty()) return found;
  const double mx = region.width * options_.region_margin + options_.region_margin_px;
  const double my = region.height * options_.region_margin + options_.region_margin_px;
  cv::Rect window = cv::Rect(cv::Point(cvFloor(region.x - mx), cvFloor(region.y - my)),
                                   cv::Point(cvCeil(region.x + region.width + mx), cvCeil(region.y + region.height + my))) &
                          cv::Rect(0, 0, gray.cols, gray.rows);
  if (options_.full_height) {
    window.y = 0;
    window.height = gray.rows;
  }
  if (window.area() <= 0) return found;
  region_area_ += static_cast<double>(window.area()) / gray.total();
  std::vector<TagDetection> fine = fine_.detect(gray(window));  // detect() copies a non-continuous view
  for (TagDetection& d : fine) {
    for (auto& c : d.corners_px) c += Eigen::Vector2d(window.x, window.y);
    d.center_px += Eigen::Vector2d(window.x, window.y);
  }
  // The full-resolution pass wins inside its window; fast-pass tags outside it are kept.
  for (const TagDetection& d : found)
    if (std::none_of(fine.begin(), fine.end(), [&](const TagDetection& f) { return f.id == d.id; })) fine.push_back(d);
  return fine;
}

}  // namespace cpgait::video
