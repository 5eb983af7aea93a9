// AprilTag capture, piece by piece: camera model and calibration files, detection on rendered images
// (accuracy, corner order, pixel convention, degradations), triangulation, single-view poses, tag sets,
// frame pairing and bad input.
#include <gtest/gtest.h>

#include <apriltag.h>
#include <tag36h11.h>
#include <tagStandard41h12.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "cpgait/capture/input_error.h"
#include "cpgait/fixtures/tag_footage.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/video/tag_family.h"
#include "cpgait/video/tag_markers.h"
#include "cpgait/video/capture_markers.h"
#include "cpgait/video/tag_pose.h"
#include "cpgait/video/triangulate.h"

#include "test_support.h"

using namespace cpgait;
namespace fs = std::filesystem;

namespace {

// Tags spread over a camera's view, each turned by up to `tilt_rad` away from facing the camera.
struct TagScene {
  std::vector<Eigen::Isometry3d> world_from_tag;
  std::vector<int> ids;
  double size_m;
};
TagScene facing_tags(const video::Camera& cam, int rows, int cols, double size_m, double tilt_rad, double distance_m,
                     std::uint32_t seed, int first_id = 0, double spread = 0.4) {
  TagScene s{{}, {}, size_m};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Matrix3d R_wc = cam.rotation_cam_from_world.transpose();
  const Eigen::Vector3d eye = cam.position_world_m();
  const double half_w = spread * cam.width_px / cam.fx_px * distance_m, half_h = spread * cam.height_px / cam.fy_px * distance_m;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double x = cols == 1 ? 0 : -half_w + 2 * half_w * c / (cols - 1);
      const double y = rows == 1 ? 0 : -half_h + 2 * half_h * r / (rows - 1);
      Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
      X.linear() = R_wc * (Eigen::AngleAxisd(tilt_rad * u(rng), Eigen::Vector3d::UnitX()) *
                           Eigen::AngleAxisd(tilt_rad * u(rng), Eigen::Vector3d::UnitY()) *
                           Eigen::AngleAxisd(3.14159 * u(rng), Eigen::Vector3d::UnitZ()))
                              .toRotationMatrix();
      X.translation() = eye + R_wc * Eigen::Vector3d(x, y, distance_m);
      s.world_from_tag.push_back(X);
      s.ids.push_back(first_id + r * cols + c);
    }
  return s;
}

cv::Mat render(const video::Camera& cam, const TagScene& s, const std::string& family, double noise = 1.0) {
  fixtures::RenderOptions ro;
  ro.noise_sigma = noise;
  const fixtures::ViewRenderer renderer(cam, ro);
  std::vector<cv::Mat> textures;
  std::vector<fixtures::Quad> quads;
  for (std::size_t i = 0; i < s.ids.size(); ++i) {
    textures.push_back(fixtures::tag_texture(family, s.ids[i]));
    quads.push_back(fixtures::tag_quad(family, s.size_m, s.world_from_tag[i], static_cast<int>(i)));
  }
  std::mt19937 rng(3);
  return renderer.render({quads}, textures, rng);
}

struct DetectionCheck {
  int found = 0;
  int wrong_ids = 0;
  double max_corner_error_px = 0;
  double mean_corner_error_px = 0;
  Eigen::Vector2d mean_offset_px = Eigen::Vector2d::Zero();
};
DetectionCheck check(const video::Camera& cam, const TagScene& s, const std::vector<video::TagDetection>& found) {
  DetectionCheck c;
  int n = 0;
  for (const auto& d : found) {
    const auto it = std::find(s.ids.begin(), s.ids.end(), d.id);
    if (it == s.ids.end()) {
      ++c.wrong_ids;
      continue;
    }
    ++c.found;
    const auto corners = video::tag_corners_in_tag_frame(s.size_m);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d truth = video::project(cam, s.world_from_tag[static_cast<std::size_t>(it - s.ids.begin())] * corners[static_cast<std::size_t>(k)]);
      const Eigen::Vector2d e = d.corners_px[static_cast<std::size_t>(k)] - truth;
      c.max_corner_error_px = std::max(c.max_corner_error_px, e.norm());
      c.mean_corner_error_px += e.norm();
      c.mean_offset_px += e;
      ++n;
    }
  }
  if (n) {
    c.mean_corner_error_px /= n;
    c.mean_offset_px /= n;
  }
  return c;
}

video::TagDetectorOptions full_resolution() {
  video::TagDetectorOptions o;
  o.quad_decimate = 1.0f;
  return o;
}

}  // namespace

// The families' geometry is known without loading the AprilTag library; it must be the library's.
TEST(TagFamily, TableMatchesTheAprilTagLibrary) {
  struct Family {
    const char* name;
    apriltag_family_t* (*create)();
    void (*destroy)(apriltag_family_t*);
  };
  for (const Family& f : {Family{"tag36h11", tag36h11_create, tag36h11_destroy},
                          Family{"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy}}) {
    apriltag_family_t* lib = f.create();
    const video::TagFamilyInfo ours = video::tag_family_info(f.name);
    EXPECT_EQ(ours.total_width, lib->total_width) << f.name;
    EXPECT_EQ(ours.width_at_border, lib->width_at_border) << f.name;
    EXPECT_EQ(ours.num_codes, static_cast<int>(lib->ncodes)) << f.name;
    f.destroy(lib);
  }
  EXPECT_THROW(video::tag_family_info("tag16h5"), std::invalid_argument);
}

TEST(Camera, ProjectionAndUndistortionInvertEachOther) {
  const video::Camera cam = fixtures::lab_rig()[1];
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p_cam(0.5 * u(rng), 0.3 * u(rng), 3 + u(rng));
    const Eigen::Vector3d p_world = cam.rotation_cam_from_world.transpose() * (p_cam - cam.translation_cam_from_world_m);
    const Eigen::Vector2d px = video::project(cam, p_world);
    const Eigen::Vector2d n = video::undistort_to_normalized(cam, px);
    EXPECT_NEAR(n.x(), p_cam.x() / p_cam.z(), 1e-10);
    EXPECT_NEAR(n.y(), p_cam.y() / p_cam.z(), 1e-10);
  }
  EXPECT_TRUE(std::isnan(video::project(cam, cam.position_world_m() - 2 * cam.rotation_cam_from_world.row(2).transpose()).x()));
}

TEST(Camera, CalibrationFilesRoundTripInJsonAndOpenCvYaml) {
  const std::string dir = cpgait::refdata::temp_dir("video_calfiles");
  const video::CameraRig rig = fixtures::lab_rig();
  video::write_calibration(rig, dir + "/rig.json");
  const video::CameraRig back = video::read_calibration(dir + "/rig.json");
  ASSERT_EQ(back.size(), rig.size());
  for (std::size_t i = 0; i < rig.size(); ++i) {
    EXPECT_EQ(back[i].name, rig[i].name);
    EXPECT_DOUBLE_EQ(back[i].fx_px, rig[i].fx_px);
    EXPECT_NEAR((back[i].position_world_m() - rig[i].position_world_m()).norm(), 0, 1e-12);
    EXPECT_DOUBLE_EQ(back[i].distortion[0], rig[i].distortion[0]);
  }
  // OpenCV's own FileStorage, as calibrateCamera samples write it (one camera, rvec/tvec extrinsics).
  {
    cv::FileStorage fs(dir + "/cam.yml", cv::FileStorage::WRITE);
    const auto& c = rig[2];
    fs << "image_width" << c.width_px << "image_height" << c.height_px;
    fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1);
    fs << "distortion_coefficients" << (cv::Mat_<double>(1, 5) << c.distortion[0], c.distortion[1], c.distortion[2], c.distortion[3], 0);
    const Eigen::AngleAxisd aa(c.rotation_cam_from_world);
    const Eigen::Vector3d r = aa.angle() * aa.axis();
    fs << "rvec" << (cv::Mat_<double>(3, 1) << r.x(), r.y(), r.z());
    fs << "tvec" << (cv::Mat_<double>(3, 1) << c.translation_cam_from_world_m.x(), c.translation_cam_from_world_m.y(),
                     c.translation_cam_from_world_m.z());
  }
  const video::CameraRig yml = video::read_calibration(dir + "/cam.yml");
  ASSERT_EQ(yml.size(), 1u);
  EXPECT_NEAR((yml[0].position_world_m() - rig[2].position_world_m()).norm(), 0, 1e-9);
  EXPECT_DOUBLE_EQ(yml[0].cx_px, rig[2].cx_px);
}

TEST(Camera, BadCalibrationFilesNameTheField) {
  auto field_of = [](const std::string& text) {
    try {
      video::parse_calibration_json(text, "cal.json");
    } catch (const InputError& e) {
      return e.field() + "@" + std::to_string(e.line());
    }
    return std::string("no error");
  };
  EXPECT_EQ(field_of(R"({"cameras": [{"name": "a", "width": 10, "height": 10, "fy": 1, "cx": 1, "cy": 1}]})"), "cameras[0].fx@0");
  EXPECT_EQ(field_of(R"({"cameras": [{"name": "a", "width": 10, "height": 10, "fx": "big", "fy": 1, "cx": 1, "cy": 1}]})"),
            "cameras[0].fx@0");
  EXPECT_EQ(field_of(R"({"cameras": [{"width": 10, "height": 10, "fx": 1, "fy": 1, "cx": 1, "cy": 1, "rotation_cam_from_world": [1,0,0,0,1,0,0,0,2]}]})"),
            "cameras[0].rotation_cam_from_world@0");
  EXPECT_EQ(field_of("{\n\"cameras\": [\n{\"width\": 10,,}]}"), "@3");
  EXPECT_EQ(field_of(R"({"cameras": []})"), "cameras@0");
  EXPECT_THROW(video::read_calibration("/nonexistent/cal.yml"), InputError);
}

TEST(TagDetection, CornersMatchTheProjectedTagCornersInOrder) {
  const video::Camera cam = fixtures::lab_rig()[0];
  for (const std::string family : {"tag36h11", "tagStandard41h12"}) {
    const TagScene s = facing_tags(cam, 3, 4, 0.1, 0.5, 3.0, 11);
    video::TagDetectorOptions o = full_resolution();
    o.family = family;
    const auto found = video::TagDetector(o).detect(render(cam, s, family, 0.0));
    const DetectionCheck c = check(cam, s, found);
    EXPECT_EQ(c.found, 12) << family;
    EXPECT_EQ(c.wrong_ids, 0) << family;
    // Sub-pixel corners, and no half-pixel bias (AprilTag's i + 0.5 centres are converted).
    EXPECT_LT(c.max_corner_error_px, 0.35) << family;
    EXPECT_LT(c.mean_corner_error_px, 0.12) << family;
    EXPECT_LT(c.mean_offset_px.norm(), 0.05) << family;
    std::printf("[ info ] %s: 12 tags, corner error mean %.3f px, max %.3f px, bias (%.3f, %.3f) px\n", family.c_str(),
                c.mean_corner_error_px, c.max_corner_error_px, c.mean_offset_px.x(), c.mean_offset_px.y());
  }
}

TEST(TagDetection, HoldsUpUnderDegradation) {
  const video::Camera cam = fixtures::lab_rig()[0];
  const TagScene s = facing_tags(cam, 3, 4, 0.1, 0.4, 3.0, 21);
  const cv::Mat clean = render(cam, s, "tag36h11", 1.0);
  const video::TagDetector detector(full_resolution());
  struct Case {
    std::string name;
    cv::Mat image;
    int min_found;
    double max_mean_error_px;
  };
  std::vector<Case> cases;
  cv::Mat img;
  cv::GaussianBlur(clean, img, cv::Size(0, 0), 1.2);
  cases.push_back({"gaussian blur 1.2 px", img.clone(), 12, 0.3});
  cv::Mat kernel = cv::Mat::zeros(1, 9, CV_32F) + 1.0f / 9;
  cv::filter2D(clean, img, -1, kernel);
  cases.push_back({"motion blur 9 px", img.clone(), 11, 0.6});
  cv::Mat noise(clean.size(), CV_16S);
  cv::randn(noise, 0, 12);
  clean.convertTo(img, CV_16S);
  img += noise;
  img.convertTo(img, CV_8U);
  cases.push_back({"noise sigma 12", img.clone(), 12, 0.3});
  std::vector<unsigned char> jpeg;
  cv::imencode(".jpg", clean, jpeg, {cv::IMWRITE_JPEG_QUALITY, 25});
  cases.push_back({"JPEG quality 25", cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE), 12, 0.3});
  clean.convertTo(img, -1, 0.35, 20);  // dim and low contrast
  cases.push_back({"low light", img.clone(), 12, 0.3});
  for (const Case& c : cases) {
    const DetectionCheck r = check(cam, s, detector.detect(c.image));
    EXPECT_GE(r.found, c.min_found) << c.name;
    EXPECT_EQ(r.wrong_ids, 0) << c.name;
    EXPECT_LT(r.mean_corner_error_px, c.max_mean_error_px) << c.name;
    std::printf("[ info ] %-22s found %d/12, corner error mean %.3f px, max %.3f px\n", c.name.c_str(), r.found,
                r.mean_corner_error_px, r.max_corner_error_px);
  }
}

TEST(TagDetection, StrongPerspectiveOcclusionAndManyTags) {
  const video::Camera cam = fixtures::lab_rig()[2];
  const video::TagDetector detector(full_resolution());
  // Strong perspective: tags turned 60-70 degrees from the camera.
  {
    TagScene s = facing_tags(cam, 2, 4, 0.12, 0.0, 2.5, 4);
    for (std::size_t i = 0; i < s.ids.size(); ++i)
      s.world_from_tag[i].linear() = s.world_from_tag[i].linear() *
                                     Eigen::AngleAxisd((i % 2 ? 1 : -1) * (1.05 + 0.02 * static_cast<double>(i)), Eigen::Vector3d::UnitY()).toRotationMatrix();
    const DetectionCheck r = check(cam, s, detector.detect(render(cam, s, "tag36h11")));
    EXPECT_GE(r.found, 6);  // at least three in four, seen at 60-70 degrees
    EXPECT_EQ(r.wrong_ids, 0);
    EXPECT_LT(r.mean_corner_error_px, 0.3);
    std::printf("[ info ] perspective 60-70 deg: found %d/8, corner error mean %.3f px\n", r.found, r.mean_corner_error_px);
  }
  // Partial occlusion: a bar across half of the tags. Occluded tags may be lost, never misread.
  {
    const TagScene s = facing_tags(cam, 2, 4, 0.12, 0.3, 3.0, 8);
    cv::Mat img = render(cam, s, "tag36h11");
    int occluded = 0;
    for (std::size_t i = 0; i < s.ids.size(); i += 2) {
      const Eigen::Vector2d c = video::project(cam, s.world_from_tag[i].translation());
      cv::rectangle(img, cv::Point(cvRound(c.x()) - 6, cvRound(c.y()) - 60), cv::Point(cvRound(c.x()) + 6, cvRound(c.y()) + 60),
                    cv::Scalar(90), cv::FILLED);
      ++occluded;
    }
    const DetectionCheck r = check(cam, s, detector.detect(img));
    EXPECT_GE(r.found, 8 - occluded);
    EXPECT_EQ(r.wrong_ids, 0);
    EXPECT_LT(r.max_corner_error_px, 0.5);
    std::printf("[ info ] occlusion: %d of 8 tags barred, %d found, none misread\n", occluded, r.found);
  }
  // Many tags: 70 in one 720p image.
  {
    const TagScene s = facing_tags(cam, 7, 10, 0.05, 0.3, 2.0, 9, 100);
    const DetectionCheck r = check(cam, s, detector.detect(render(cam, s, "tag36h11")));
    EXPECT_GE(r.found, 68);
    EXPECT_EQ(r.wrong_ids, 0);
    EXPECT_LT(r.mean_corner_error_px, 0.2);
    std::printf("[ info ] many tags: found %d/70, corner error mean %.3f px\n", r.found, r.mean_corner_error_px);
  }
}

TEST(TagDetection, TrackerRegionPassMatchesFullResolution) {
  const video::Camera cam = fixtures::lab_rig()[0];
  // Six small tags (16 px: too small for the decimated pass) around one near, large one.
  const TagScene s = facing_tags(cam, 2, 3, 0.04, 0.4, 3.2, 31, 0, 0.12);
  TagScene with_big = s;
  const Eigen::Matrix3d R_wc = cam.rotation_cam_from_world.transpose();
  Eigen::Isometry3d big = Eigen::Isometry3d::Identity();
  big.linear() = R_wc;
  big.translation() = cam.position_world_m() + R_wc * Eigen::Vector3d(0.0, 0.0, 0.8);
  with_big.world_from_tag.push_back(big);
  with_big.ids.push_back(50);
  const cv::Mat img = render(cam, with_big, "tag36h11");
  video::TagDetectorOptions fast;
  fast.quad_decimate = 3.0f;
  const int fast_only = check(cam, with_big, video::TagDetector(fast).detect(img)).found;
  const int full = check(cam, with_big, video::TagDetector(full_resolution()).detect(img)).found;
  video::TagTracker tracker(fast);
  tracker.detect(img);  // first frame: the region comes from the fast pass only
  const DetectionCheck tracked = check(cam, with_big, tracker.detect(img));
  EXPECT_LT(fast_only, full);
  EXPECT_EQ(tracked.found, full);
  EXPECT_GT(tracker.region_fraction(), 0.0);
  EXPECT_LT(tracker.region_fraction(), 0.8);
}

TEST(Triangulation, RecoversPointsAndDropsAMisdetectedView) {
  const video::CameraRig rig = fixtures::lab_rig();
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0, 0.1);
  std::uniform_real_distribution<double> u(-1, 1);
  double worst = 0;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d X(0.6 * u(rng), 0.8 + 0.6 * u(rng), 0.3 * u(rng));
    std::vector<video::PixelObservation> obs;
    for (int c = 0; c < 4; ++c) obs.push_back({c, video::project(rig[static_cast<std::size_t>(c)], X) + Eigen::Vector2d(noise(rng), noise(rng))});
    const auto p = video::triangulate_point(rig, obs);
    ASSERT_TRUE(p.valid());
    worst = std::max(worst, (p.position_m - X).norm());
    EXPECT_EQ(p.views_used, 4);
  }
  EXPECT_LT(worst, 1.5e-3);
  // One camera's corner 15 px off (a wrong corner): that view goes, the point stays accurate.
  const Eigen::Vector3d X(0.1, 0.9, 0.05);
  std::vector<video::PixelObservation> obs;
  for (int c = 0; c < 4; ++c) obs.push_back({c, video::project(rig[static_cast<std::size_t>(c)], X)});
  obs[2].pixel += Eigen::Vector2d(15, -4);
  const auto p = video::triangulate_point(rig, obs);
  ASSERT_TRUE(p.valid());
  EXPECT_EQ(p.views_used, 3);
  ASSERT_EQ(p.rejected_cameras.size(), 1u);
  EXPECT_EQ(p.rejected_cameras[0], 2);
  EXPECT_LT((p.position_m - X).norm(), 1e-6);
  // Two views that disagree cannot be told apart: no point rather than a wrong one.
  const auto q = video::triangulate_point(rig, {obs[0], obs[2]});
  EXPECT_FALSE(q.valid());
}

TEST(TagPose, SingleViewPoseOfANearTag) {
  const video::Camera cam = fixtures::lab_rig()[3];
  const TagScene s = facing_tags(cam, 1, 1, 0.15, 0.5, 1.5, 41);
  const auto found = video::TagDetector(full_resolution()).detect(render(cam, s, "tag36h11", 0.5));
  ASSERT_EQ(found.size(), 1u);
  const video::TagPose pose = video::tag_pose_ippe(cam, found[0], s.size_m);
  Eigen::Isometry3d cam_from_world = Eigen::Isometry3d::Identity();
  cam_from_world.linear() = cam.rotation_cam_from_world;
  cam_from_world.translation() = cam.translation_cam_from_world_m;
  const Eigen::Isometry3d cam_from_tag = cam_from_world * s.world_from_tag[0];
  EXPECT_LT((pose.translation_cam_from_tag_m - cam_from_tag.translation()).norm(), 5e-3);
  EXPECT_LT(Eigen::AngleAxisd(pose.rotation_cam_from_tag.transpose() * cam_from_tag.linear()).angle(), 0.05);
  EXPECT_LT(pose.rms_reprojection_px, 0.5);
}

TEST(TagSet, JsonRoundTripMarkersAndErrors) {
  const fixtures::TaggedWalker w = fixtures::tagged_walker();
  const video::TagSet back = video::parse_tag_set_json(video::format_tag_set_json(w.tags), "tags.json");
  ASSERT_EQ(back.tags.size(), w.tags.tags.size());
  for (std::size_t i = 0; i < back.tags.size(); ++i)
    for (int k = 0; k < 4; ++k)
      EXPECT_NEAR((back.tags[i].corner_in_body_m(k) - w.tags.tags[i].corner_in_body_m(k)).norm(), 0, 1e-12);
  // Corner k of every tag sits where tag_corners_in_tag_frame puts it: a square of the tag's size.
  const auto& t = w.tags.tags[0];
  EXPECT_NEAR((t.corner_in_body_m(0) - t.corner_in_body_m(1)).norm(), t.size_m, 1e-12);
  EXPECT_NEAR((t.corner_in_body_m(0) - t.corner_in_body_m(2)).norm(), t.size_m * std::sqrt(2.0), 1e-12);
  auto field_of = [](const std::string& text) {
    try {
      video::parse_tag_set_json(text, "tags.json");
    } catch (const InputError& e) {
      return e.field();
    }
    return std::string("no error");
  };
  EXPECT_EQ(field_of(R"({"family": "tag99h1", "tags": []})"), "family");
  EXPECT_EQ(field_of(R"({"tags": [{"id": 1, "body": "a", "size_m": 80, "position_m": [0,0,0]}]})"), "tags[0].size_m");
  EXPECT_EQ(field_of(R"({"tags": [{"id": 1, "body": "a", "size_m": 0.08, "position_m": [0,0,0]},
                                  {"id": 1, "body": "b", "size_m": 0.08, "position_m": [0,0,0]}]})"), "tags[1].id");
  EXPECT_EQ(field_of(R"({"tags": [{"id": 600, "body": "a", "size_m": 0.08, "position_m": [0,0,0]}]})"), "tags[0].id");
  EXPECT_EQ(field_of(R"({"tags": [{"id": 1, "size_m": 0.08, "position_m": [0,0,0]}]})"), "tags[0].body");
  video::TagSet bad = w.tags;
  bad.tags[3].body = "head";
  try {
    video::with_tag_markers(w.model, bad, "tags.json");
    ADD_FAILURE() << "unknown body accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "tags[3].body");
  }
}

namespace {
// Detections made by projecting the walker's tag corners (no rendering): for frame pairing, gap
// filling and warnings.
std::vector<video::CameraFootage> projected_footage(const fixtures::TaggedWalker& w, const video::CameraRig& rig,
                                                    const Eigen::MatrixXd& q, std::vector<Eigen::Matrix3Xd>& truth) {
  std::vector<video::CameraFootage> footage(rig.size());
  KinematicsWorkspace<double> ws(w.model);
  truth.clear();
  for (Eigen::Index f = 0; f < q.rows(); ++f) {
    const Eigen::VectorXd qf = q.row(f).transpose();
    forward_kinematics(w.model, qf.data(), ws);
    Eigen::Matrix3Xd corners(3, 4 * static_cast<Eigen::Index>(w.tags.tags.size()));
    for (std::size_t t = 0; t < w.tags.tags.size(); ++t)
      for (int k = 0; k < 4; ++k)
        corners.col(static_cast<Eigen::Index>(4 * t) + k) =
            marker_position(w.model, w.model.marker_index(w.tags.tags[t].corner_markers[static_cast<std::size_t>(k)]), ws);
    truth.push_back(corners);
    for (std::size_t c = 0; c < rig.size(); ++c) {
      std::vector<video::TagDetection> frame;
      for (std::size_t t = 0; t < w.tags.tags.size(); ++t) {
        video::TagDetection d;
        d.id = w.tags.tags[t].id;
        d.decision_margin = 100;
        for (int k = 0; k < 4; ++k) d.corners_px[static_cast<std::size_t>(k)] = video::project(rig[c], corners.col(static_cast<Eigen::Index>(4 * t) + k));
        frame.push_back(d);
      }
      footage[c].camera = static_cast<int>(c);
      footage[c].frame_rate_hz = 60;
      footage[c].frames.push_back(frame);
    }
  }
  return footage;
}
}  // namespace

TEST(Capture, FillsShortGapsPairsFramesByTimeAndWarns) {
  const fixtures::TaggedWalker w = fixtures::tagged_walker();
  const video::CameraRig rig = fixtures::lab_rig();
  Eigen::MatrixXd q(40, w.model.num_coordinates());
  const int hip = w.model.coordinate_index("hip_flexion_r"), tx = w.model.coordinate_index("pelvis_tx"),
            ty = w.model.coordinate_index("pelvis_ty");
  for (int f = 0; f < 40; ++f) {
    q.row(f) = w.model.default_coordinates().transpose();
    q(f, hip) = 0.4 * std::sin(f / 60.0 * 5);
    q(f, tx) = -0.3 + f / 60.0;
    q(f, ty) = 0.93;
  }
  std::vector<Eigen::Matrix3Xd> truth;
  auto footage = projected_footage(w, rig, q, truth);
  // Tag 7 (right thigh, front) vanishes from every camera for frames 20-21; an unknown tag appears.
  for (auto& f : footage) {
    for (int i : {20, 21}) {
      auto& fr = f.frames[static_cast<std::size_t>(i)];
      fr.erase(std::remove_if(fr.begin(), fr.end(), [](const video::TagDetection& d) { return d.id == 7; }), fr.end());
    }
    video::TagDetection stranger;
    stranger.id = 333;
    f.frames[5].push_back(stranger);
  }
  footage[3].frames.pop_back();  // one camera is a frame short
  const video::CaptureResult r = video::triangulate_footage(rig, w.tags, footage);
  EXPECT_EQ(r.summary.num_frames, 39);
  const int m = 4 * 7;
  EXPECT_EQ(r.views(20, m), -1);
  EXPECT_EQ(r.views(21, m), -1);
  EXPECT_EQ(r.views(22, m), 4);
  EXPECT_LT((r.markers.position_m(20, m) - truth[20].col(m)).norm(), 1e-3);
  EXPECT_EQ(r.summary.corners_filled, 8);
  auto warned = [&](const std::string& what) {
    return std::any_of(r.summary.warnings.begin(), r.summary.warnings.end(), [&](const std::string& s) { return s.find(what) != std::string::npos; });
  };
  EXPECT_TRUE(warned("tag 333"));
  EXPECT_TRUE(warned("has 39 frames"));
  // Without gap filling the frames stay empty.
  video::CaptureOptions no_fill;
  no_fill.max_gap_fill_s = 0;
  EXPECT_EQ(video::triangulate_footage(rig, w.tags, footage, no_fill).views(20, m), 0);

  // Time sync: camera 1 started 2 frames late (its frame i shows time (i + 2) / 60 on camera 0's clock).
  video::CameraRig shifted = rig;
  shifted[1].time_offset_s = -2 / 60.0;
  auto late = footage;
  late[1].frames.erase(late[1].frames.begin(), late[1].frames.begin() + 2);
  video::CaptureOptions by_time;
  by_time.sync = video::CaptureOptions::Sync::kTime;
  const video::CaptureResult t = video::triangulate_footage(shifted, w.tags, late, by_time);
  EXPECT_EQ(t.views(10, 0), 4);
  EXPECT_EQ(t.summary.views_rejected, 0);
  EXPECT_LT((t.markers.position_m(10, 0) - truth[10].col(0)).norm(), 1e-6);
  // The same footage paired by index: camera 1's views are two frames off and get rejected.
  const video::CaptureResult wrong = video::triangulate_footage(rig, w.tags, late);
  EXPECT_GT(wrong.summary.views_rejected, 0);
}

TEST(Capture, BadVideosAndCamerasGetClearErrors) {
  const std::string dir = cpgait::refdata::temp_dir("video_badvideo");
  const video::CameraRig rig = fixtures::lab_rig();
  const video::TagSet tags = fixtures::tagged_walker().tags;
  { std::ofstream(dir + "/cam0.avi") << "this is not a video\n"; }
  try {
    video::capture_markers(rig, tags, {dir + "/cam0.avi"});
    ADD_FAILURE() << "a text file decoded as video";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam0.avi"), std::string::npos) << e.what();
  }
  try {
    video::capture_markers(rig, tags, {dir + "/cam9.avi"});
    ADD_FAILURE() << "a video for a camera the calibration lacks was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam9"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("cam0, cam1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(video::capture_markers(rig, tags, {"cam1=" + dir + "/missing.avi"}), InputError);
  EXPECT_THROW(video::match_videos_to_cameras(rig, {"cam1=a.avi", "cam1=b.avi"}), InputError);
}

TEST(Capture, SingleViewPoseStandsInOnlyForALostSegment) {
  const fixtures::TaggedWalker w = fixtures::tagged_walker();
  const video::CameraRig rig = fixtures::lab_rig();
  Eigen::MatrixXd q(3, w.model.num_coordinates());
  for (int f = 0; f < 3; ++f) q.row(f) = w.model.default_coordinates().transpose();
  std::vector<Eigen::Matrix3Xd> truth;
  auto footage = projected_footage(w, rig, q, truth);
  // Frame 1: the right foot's tags (10, 11, 12) vanish, except tag 10 in camera 3.
  for (std::size_t c = 0; c < footage.size(); ++c) {
    auto& fr = footage[c].frames[1];
    fr.erase(std::remove_if(fr.begin(), fr.end(), [&](const video::TagDetection& d) { return d.id >= 10 && d.id <= 12 && !(c == 3 && d.id == 10); }),
             fr.end());
  }
  video::CaptureOptions o;
  o.min_single_view_edge_px = 10;  // these tags are ~25 px across at 3 m
  o.max_gap_fill_s = 0;
  const video::CaptureResult r = video::triangulate_footage(rig, w.tags, footage, o);
  const int m10 = 4 * 10;
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(r.views(1, m10 + k), 1);
    EXPECT_LT((r.markers.position_m(1, m10 + k) - truth[1].col(m10 + k)).norm(), 1e-4);  // exact pixels: IPPE is exact
  }
  EXPECT_EQ(r.views(1, 4 * 11), 0);
  EXPECT_EQ(r.summary.corners_single_view, 4);
  // Tag 8 (right shank) seen by one camera while its segment has another tag triangulated: not used.
  auto footage2 = footage;
  for (std::size_t c = 1; c < footage2.size(); ++c) {
    auto& fr = footage2[c].frames[2];
    fr.erase(std::remove_if(fr.begin(), fr.end(), [](const video::TagDetection& d) { return d.id == 8; }), fr.end());
  }
  const video::CaptureResult r2 = video::triangulate_footage(rig, w.tags, footage2, o);
  EXPECT_EQ(r2.views(2, 4 * 8), 0);
  EXPECT_EQ(r2.views(2, 4 * 9), 4);
  // With the default edge threshold (60 px) these small tags never stand in.
  o.min_single_view_edge_px = 60;
  EXPECT_EQ(video::triangulate_footage(rig, w.tags, footage, o).summary.corners_single_view, 0);
}

TEST(Capture, CentreMarkersAreTheCornersMean) {
  fixtures::TaggedWalker w = fixtures::tagged_walker();
  w.tags.tags[1].center_marker = "RPELVIS";
  const video::TagSet set = video::parse_tag_set_json(video::format_tag_set_json(w.tags), "tags.json");
  ASSERT_EQ(set.tags[1].center_marker, "RPELVIS");
  const Model model = video::with_tag_markers(w.model, set);
  ASSERT_GE(model.marker_index("RPELVIS"), 0);
  const video::CameraRig rig = fixtures::lab_rig();
  Eigen::MatrixXd q(2, w.model.num_coordinates());
  for (int f = 0; f < 2; ++f) q.row(f) = w.model.default_coordinates().transpose();
  std::vector<Eigen::Matrix3Xd> truth;
  const auto footage = projected_footage(w, rig, q, truth);
  const video::CaptureResult r = video::triangulate_footage(rig, set, footage);
  const int m = r.markers.marker_index("RPELVIS");
  ASSERT_EQ(m, 4 * static_cast<int>(set.tags.size()));  // after every corner
  KinematicsWorkspace<double> ws(model);
  const Eigen::VectorXd q0 = q.row(0).transpose();
  forward_kinematics(model, q0.data(), ws);
  EXPECT_LT((r.markers.position_m(0, m) - marker_position(model, model.marker_index("RPELVIS"), ws)).norm(), 1e-6);
  EXPECT_EQ(r.views(0, m), r.views(0, 4));
  EXPECT_NE(video::format_marker_set_xml(set).find("RPELVIS"), std::string::npos);
}
