// Acceptance of the AprilTag path on rendered footage with exact ground truth: a tagged walker filmed
// by four 1280x720 cameras (lens distortion, motion blur, lighting changes, sensor noise, MJPG
// compression, segments occluding one another), and a calibration board moved through the volume.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "cpgait/fixtures/tag_footage.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/video/tag_markers.h"
#include "cpgait/video/calibrate_cameras.h"
#include "cpgait/video/capture_markers.h"
#include "cpgait/video/register_tags.h"
#include <random>

#include "test_support.h"

using namespace cpgait;
namespace fs = std::filesystem;

namespace {
double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}
}  // namespace

TEST(CaptureFootage, WalkerFromFourCamerasTriangulatesAndTracksJointAngles) {
  const std::string dir = cpgait::refdata::temp_dir("footage_walk");
  fixtures::FootageOptions fo;
  fo.render.blur_samples = 3;
  fo.render.exposure_s = 1.0 / 500;  // 2 ms shutter, as gait video uses
  const fixtures::WalkFootage wf = fixtures::render_walk_footage(dir, fo);
  const video::CameraRig rig = video::read_calibration(wf.calibration_path);
  const video::TagSet tags = video::read_tag_set(wf.tags_path);
  const video::CaptureResult r = video::capture_markers(rig, tags, wf.videos);
  std::printf("[ info ] %s\n", r.summary.BriefReport().c_str());

  std::vector<double> triangulated_mm, single_mm, filled_mm;
  for (int f = 0; f < r.markers.num_frames(); ++f)
    for (int m = 0; m < r.markers.num_markers(); ++m) {
      const int v = r.views(f, m);
      if (v == 0) continue;
      const double e = 1000 * (r.markers.position_m(f, m) - wf.corners_world_m[static_cast<std::size_t>(f)].col(m)).norm();
      (v >= 2 ? triangulated_mm : v == 1 ? single_mm : filled_mm).push_back(e);

    }
  std::vector<double> all_mm = triangulated_mm;
  all_mm.insert(all_mm.end(), single_mm.begin(), single_mm.end());
  all_mm.insert(all_mm.end(), filled_mm.begin(), filled_mm.end());
  std::printf("[ info ] 3-D corner error, triangulated (%zu): median %.3f mm, p95 %.3f mm, max %.3f mm\n", triangulated_mm.size(),
              percentile(triangulated_mm, 0.5), percentile(triangulated_mm, 0.95), percentile(triangulated_mm, 1.0));
  std::printf("[ info ] single-view IPPE (%zu): median %.2f mm, p95 %.2f mm; gap-filled (%zu): median %.2f mm, p95 %.2f mm; "
              "all output corners (%zu): median %.3f mm, p95 %.3f mm\n",
              single_mm.size(), percentile(single_mm, 0.5), percentile(single_mm, 0.95), filled_mm.size(), percentile(filled_mm, 0.5),
              percentile(filled_mm, 0.95), all_mm.size(), percentile(all_mm, 0.5), percentile(all_mm, 0.95));
  ASSERT_GT(triangulated_mm.size(), 0.6 * r.markers.num_frames() * r.markers.num_markers());
  // Target: median 2 mm (the GUIDE), p95 5 mm. Measured 0.26 and 0.73 mm: regression bounds 1.0 and 3.0 mm.
  EXPECT_TRUE(cpgait::refdata::within_target_and_regression(percentile(triangulated_mm, 0.5), 2.0, 1.0)) << "triangulated median (mm)";
  EXPECT_TRUE(cpgait::refdata::within_target_and_regression(percentile(triangulated_mm, 0.95), 5.0, 3.0)) << "triangulated p95 (mm)";
  // Gap-filled corners (measured 32: median 0.38 mm, p95 1.22 mm): held at 1.5 and 5 mm.
  ASSERT_GT(filled_mm.size(), 10u);
  EXPECT_LE(percentile(filled_mm, 0.5), 1.5);
  EXPECT_LE(percentile(filled_mm, 0.95), 5.0);
  // Single-view corners: none on this footage (every tag that IPPE would place is seen by two cameras
  // or too small), so nothing to hold here; Capture.SingleViewPoseStandsInOnlyForALostSegment does.
  if (single_mm.empty()) {
    std::printf("[ info ] not asserted: no corner came from a single view on this footage\n");
  } else {
    EXPECT_LE(percentile(single_mm, 0.5), 10.0) << "single-view median (mm)";
  }

  // IK on the captured markers, as any TRC: joint angles against the truth.
  const fixtures::TaggedWalker w = fixtures::tagged_walker();
  const IkResult ik = inverse_kinematics(w.model, r.markers, IkTaskSet{});
  std::printf("[ info ] %s\n[ info ] joint angle RMS error (deg):", ik.summary.BriefReport().c_str());
  double worst = 0;
  std::string worst_name;
  for (int c = 0; c < w.model.num_coordinates(); ++c) {
    if (!w.model.coordinates[static_cast<std::size_t>(c)].is_angle()) continue;
    const double rms_deg = std::sqrt((ik.q.col(c) - wf.q.col(c)).array().square().mean()) * 180 / M_PI;
    std::printf(" %s %.2f", w.model.coordinates[static_cast<std::size_t>(c)].name.c_str(), rms_deg);
    if (rms_deg > worst) {
      worst = rms_deg;
      worst_name = w.model.coordinates[static_cast<std::size_t>(c)].name;
    }
  }
  std::printf("\n[ info ] worst joint angle: %s %.3f deg RMS\n", worst_name.c_str(), worst);
  EXPECT_LT(worst, 2.0) << worst_name;

  // Registration from a static trial: tags placed by hand are off by 8-15 mm and 4-8 degrees; after
  // registering them on a standing trial, IK on the walk is about as good as with the true placement.
  auto worst_angle = [&](const video::TagSet& set) {
    const IkResult k = inverse_kinematics(video::with_tag_markers(w.model, set), r.markers, IkTaskSet{});
    double wa = 0;
    for (int c = 0; c < w.model.num_coordinates(); ++c)
      if (w.model.coordinates[static_cast<std::size_t>(c)].is_angle())
        wa = std::max(wa, std::sqrt((k.q.col(c) - wf.q.col(c)).array().square().mean()) * 180 / M_PI);
    return wa;
  };
  video::TagSet by_hand = tags;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (auto& t : by_hand.tags) {
    const Eigen::Vector3d dir = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    t.position_in_body_m += (0.008 + 0.007 * std::abs(u(rng))) * dir;
    const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    t.rotation_body_from_tag = Eigen::AngleAxisd((4 + 4 * std::abs(u(rng))) * M_PI / 180, axis) * t.rotation_body_from_tag;
  }
  fixtures::FootageOptions so;
  so.standing = true;
  so.duration_s = 0.2;
  so.rate_hz = 30;
  const fixtures::WalkFootage still = fixtures::render_walk_footage(dir + "/static", so);
  const video::CaptureResult static_markers = video::capture_markers(rig, tags, still.videos);
  video::TagRegistrationSummary rs;
  const video::TagSet registered = video::register_tag_set(w.model, by_hand, static_markers.markers, {}, &rs);
  const double hand = worst_angle(by_hand), reg = worst_angle(registered);
  std::printf("[ info ] %s\n[ info ] worst joint angle RMS on the walk: true placement %.3f deg, by hand %.3f deg, registered %.3f deg\n",
              rs.BriefReport().c_str(), worst, hand, reg);
  std::string kept;
  for (int id : rs.unchanged) kept.append(" ").append(std::to_string(id));  // not operator+: GCC 12 warns falsely (-Wrestrict)
  std::printf("[ info ] tags not seen well enough in the static trial (kept as placed):%s\n", kept.c_str());
  // Every tag the static trial saw is re-placed, its corners then fit to a third of a millimetre;
  // the walk's joint angles improve. (Tags the static trial did not see keep their error.)
  EXPECT_GE(rs.moved.size(), tags.tags.size() * 3 / 4);
  EXPECT_LT(rs.marker_rms_after_m, 0.1 * rs.marker_rms_before_m);
  EXPECT_LT(reg, 0.75 * hand);
  fs::remove_all(dir);
}

TEST(CaptureFootage, CalibrationFromTheBoardRecoversFocalLengthsAndPositions) {
  const std::string dir = cpgait::refdata::temp_dir("footage_board");
  const fixtures::BoardFootage bf = fixtures::render_board_footage(dir, 40);
  const video::CalibrationBoard board = video::make_aprilgrid(video::read_aprilgrid_spec(bf.board_path));
  const video::CameraRig truth = fixtures::lab_rig();
  std::vector<video::CameraFootage> footage;
  std::vector<std::string> names;
  for (std::size_t c = 0; c < bf.videos.size(); ++c) {
    footage.push_back(video::detect_video(static_cast<int>(c), bf.videos[c], video::TagDetectorOptions{}));
    names.push_back(fs::path(bf.videos[c]).stem().string());
  }
  video::CalibrationOptions o;
  o.reference_frame = 0;
  o.world_from_reference_board = bf.world_from_board[0];  // where the board stood in the lab
  const video::CalibrationResult r = video::calibrate_cameras(board, footage, names, o);
  std::printf("[ info ] %s\n", r.summary.BriefReport().c_str());
  ASSERT_EQ(r.rig.size(), truth.size());
  for (std::size_t c = 0; c < truth.size(); ++c) {
    const double fx_err = std::abs(r.rig[c].fx_px / truth[c].fx_px - 1), fy_err = std::abs(r.rig[c].fy_px / truth[c].fy_px - 1);
    const double pos_mm = 1000 * (r.rig[c].position_world_m() - truth[c].position_world_m()).norm();
    std::printf("[ info ] %s: fx %.2f px (%.3f%%), fy %.2f px (%.3f%%), position error %.2f mm\n", truth[c].name.c_str(),
                r.rig[c].fx_px, 100 * fx_err, r.rig[c].fy_px, 100 * fy_err, pos_mm);
    EXPECT_EQ(r.rig[c].name, truth[c].name);
    EXPECT_LT(fx_err, 0.005);
    EXPECT_LT(fy_err, 0.005);
    EXPECT_LT(pos_mm, 5.0);
  }
  EXPECT_LT(r.summary.rms_px, 0.5);
  // Board poses come back too: the last one within 5 mm of where it was.
  ASSERT_TRUE(r.world_from_board.back().has_value());
  EXPECT_LT(1000 * (r.world_from_board.back()->translation() - bf.world_from_board.back().translation()).norm(), 5.0);
  fs::remove_all(dir);
}
