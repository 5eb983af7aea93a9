#include "cpgait/video/tag_detector.h"

#include <apriltag.h>
#include <tag36h11.h>
#include <tagStandard41h12.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "cpgait/capture/input_error.h"
#include "cpgait/video/footage.h"
#include "cpgait/video/tag_family.h"

namespace cpgait::video {

namespace {

// The library's families are created and destroyed by family-specific functions.
struct FamilyHandle {
  apriltag_family_t* family = nullptr;
  void (*destroy)(apriltag_family_t*) = nullptr;
  explicit FamilyHandle(const std::string& name) {
    if (name == "tag36h11") {
      family = tag36h11_create();
      destroy = tag36h11_destroy;
    } else if (name == "tagStandard41h12") {
      family = tagStandard41h12_create();
      destroy = tagStandard41h12_destroy;
    } else {
      throw std::invalid_argument("unknown tag family '" + name + "' (expected tag36h11 or tagStandard41h12)");
    }
  }
  ~FamilyHandle() { destroy(family); }
  FamilyHandle(const FamilyHandle&) = delete;
  FamilyHandle& operator=(const FamilyHandle&) = delete;
};

}  // namespace

cv::Mat tag_bitmap(const std::string& name, int id) {
  FamilyHandle f(name);
  if (id < 0 || id >= static_cast<int>(f.family->ncodes))
    throw std::invalid_argument("tag id " + std::to_string(id) + " is not in " + name);
  image_u8_t* im = apriltag_to_image(f.family, id);
  cv::Mat out(im->height + 2, im->width + 2, CV_8UC1, cv::Scalar(255));
  for (int r = 0; r < im->height; ++r)
    for (int c = 0; c < im->width; ++c) out.at<unsigned char>(r + 1, c + 1) = im->buf[r * im->stride + c];
  image_u8_destroy(im);
  return out;
}

struct TagDetector::Impl {
  FamilyHandle family;
  apriltag_detector_t* detector = nullptr;
  explicit Impl(const TagDetectorOptions& o) : family(o.family) {
    detector = apriltag_detector_create();
    apriltag_detector_add_family_bits(detector, family.family, o.max_hamming);
    detector->quad_decimate = o.quad_decimate;
    detector->quad_sigma = o.quad_sigma;
    detector->refine_edges = o.refine_edges;
    detector->decode_sharpening = o.decode_sharpening;
    detector->nthreads = o.threads;
  }
  ~Impl() { apriltag_detector_destroy(detector); }
};

TagDetector::TagDetector(const TagDetectorOptions& options)
    : impl_(std::make_unique<Impl>(options)), options_(options) {}
TagDetector::~TagDetector() = default;

std::vector<TagDetection> TagDetector::detect(const cv::Mat& image) const {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.depth() != CV_8U) throw std::invalid_argument("tag detection needs an 8-bit image");
  if (!gray.isContinuous()) gray = gray.clone();
  image_u8_t im{gray.cols, gray.rows, static_cast<int32_t>(gray.step[0]), gray.data};
  zarray_t* found = apriltag_detector_detect(impl_->detector, &im);
  std::vector<TagDetection> out;
  out.reserve(static_cast<std::size_t>(zarray_size(found)));
  for (int i = 0; i < zarray_size(found); ++i) {
    apriltag_detection_t* d;
    zarray_get(found, i, &d);
    if (d->decision_margin < options_.min_decision_margin) continue;
    TagDetection t;
    t.id = d->id;
    t.hamming = d->hamming;
    t.decision_margin = d->decision_margin;
    for (int k = 0; k < 4; ++k) t.corners_px[static_cast<std::size_t>(k)] = {d->p[k][0] - 0.5, d->p[k][1] - 0.5};
    t.center_px = {d->c[0] - 0.5, d->c[1] - 0.5};
    out.push_back(t);
  }
  apriltag_detections_destroy(found);
  return out;
}

ImageDetections detect_image_file(const std::string& path, const TagDetectorOptions& options) {
  if (!std::filesystem::exists(path)) throw InputError(path, 0, "images", "file not found");
  const cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw InputError(path, 0, "images", "not a readable image");
  return {img.cols, img.rows, TagDetector(options).detect(img)};
}

}  // namespace cpgait::video
