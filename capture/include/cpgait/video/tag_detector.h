#pragma once
// AprilTag 3 detection. Corners come back in OpenCV's pixel convention (AprilTag puts pixel centres
// at i + 0.5; we subtract 0.5) and in AprilTag's order, which matches tag_corners_in_tag_frame().
// A TagDetector holds the library's detector state: one per thread.
#include <Eigen/Core>
#include <array>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace cpgait::video {

struct TagDetectorOptions {
  std::string family = "tag36h11";  // or "tagStandard41h12"
  // Quads are found on an image decimated by this factor; decoding and edge refinement use the full
  // image, so corner accuracy holds (AprilTag 3's recommended speed/accuracy trade-off for 720p).
  float quad_decimate = 3.0f;
  float quad_sigma = 0.0f;           // Gaussian blur before quad detection (helps very noisy images)
  bool refine_edges = true;          // snap edges to the strongest gradient: needed for sub-pixel corners
  double decode_sharpening = 0.25;   // library default; helps small and blurred tags
  int max_hamming = 1;               // bit errors corrected; 2 admits more false positives
  double min_decision_margin = 20;   // detections below are dropped as unreliable
  int threads = 1;                   // the library's own worker threads per image
};

struct TagDetection {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                            Eigen::Vector2d::Zero()};  // OpenCV convention, AprilTag's corner order
  Eigen::Vector2d center_px = Eigen::Vector2d::Zero();
  double decision_margin = 0;
  int hamming = 0;
};

class TagDetector {
 public:
  explicit TagDetector(const TagDetectorOptions& options = {});
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  // `gray` must be 8-bit single channel; colour images are converted.
  std::vector<TagDetection> detect(const cv::Mat& image) const;
  const TagDetectorOptions& options() const { return options_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  TagDetectorOptions options_;
};

}  // namespace cpgait::video
