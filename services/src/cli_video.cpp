// detect, calibrate and capture: AprilTag footage to calibrated cameras and virtual markers.
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/video/footage.h"
#include "cpgait/video/register_tags.h"
#include "cpgait/model/osim_reader.h"
#include "output_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

void add_detector_options(CLI::App* cmd, video::TagDetectorOptions& o) {
  cmd->add_option("--decimate", o.quad_decimate, "quad detection on an image decimated by this factor (decoding stays full resolution)")
      ->capture_default_str();
  cmd->add_option("--min-margin", o.min_decision_margin, "drop detections whose decision margin is below this")->capture_default_str();
  cmd->add_option("--max-hamming", o.max_hamming, "bit errors corrected (0-2)")->check(CLI::Range(0, 2))->capture_default_str();
}

nlohmann::json detection_json(const video::TagDetection& d) {
  nlohmann::json corners = nlohmann::json::array();
  for (const auto& c : d.corners_px) corners.push_back({c.x(), c.y()});
  return {{"id", d.id},
          {"corners_px", corners},
          {"center_px", {d.center_px.x(), d.center_px.y()}},
          {"decision_margin", d.decision_margin},
          {"hamming", d.hamming}};
}

// detect
void add_detect_command(CLI::App& app) {
  auto* detect = app.add_subcommand("detect",
                                    "Detect AprilTags in images and print them as JSON: per image its size and every tag's id,\n"
                                    "corners (pixels, OpenCV convention: pixel centres at integers; AprilTag's corner order),\n"
                                    "centre and decision margin.");
  struct DetectArgs {
    std::vector<std::string> images;
    video::TagDetectorOptions o;
  };
  auto d = std::make_shared<DetectArgs>();
  d->o.quad_decimate = 1.0f;  // one-off images: accuracy over speed
  detect->add_option("images", d->images, "image files (PNG, JPEG, ...)")->required();
  detect->add_option("--family", d->o.family, "tag family")->check(CLI::IsMember({"tag36h11", "tagStandard41h12"}))->capture_default_str();
  add_detector_options(detect, d->o);
  detect->callback([d] {
    nlohmann::json out = nlohmann::json::array();
    for (const std::string& path : d->images) {
      const video::ImageDetections image = video::footage().detect_image_file(path, d->o);
      nlohmann::json dets = nlohmann::json::array();
      for (const auto& t : image.tags) dets.push_back(detection_json(t));
      out.push_back({{"image", path}, {"width", image.width_px}, {"height", image.height_px}, {"family", d->o.family}, {"detections", dets}});
    }
    std::printf("%s\n", json_text(out, 2).c_str());
  });
}

// calibrate
void add_calibrate_command(CLI::App& app) {
  auto* cal = app.add_subcommand("calibrate",
                                 "Calibrate cameras from footage of an AprilGrid board (board JSON: rows, cols, tag_size_m,\n"
                                 "spacing, family, double_sided). Each video is NAME=PATH or a file named after its camera.\n"
                                 "Writes a calibration JSON (intrinsics in pixels, distortion k1 k2 p1 p2 k3, extrinsics\n"
                                 "lab->camera in metres). The lab frame is the board's frame in the reference frame, moved by\n"
                                 "--board-position-m / --board-xyz-deg (where the board stood in the lab).");
  struct CalArgs {
    std::string board, out;
    std::vector<std::string> videos;
    video::CalibrationOptions o;
    video::TagDetectorOptions det;
    std::vector<double> position{0, 0, 0}, xyz_deg{0, 0, 0};
  };
  auto c = std::make_shared<CalArgs>();
  cal->add_option("--board", c->board, "board description (.json)")->required()->check(CLI::ExistingFile);
  cal->add_option("--videos", c->videos, "one video per camera")->required();
  cal->add_option("-o,--output", c->out, "calibration JSON to write")->required();
  cal->add_option("--reference-frame", c->o.reference_frame, "frame (0-based) whose board pose defines the lab frame; -1: the frame most cameras see")
      ->capture_default_str();
  cal->add_option("--board-position-m", c->position, "board origin in the lab at the reference frame (m)")->expected(3);
  cal->add_option("--board-xyz-deg", c->xyz_deg, "board orientation in the lab (body-fixed X-Y-Z, degrees)")->expected(3);
  cal->add_flag("!--free-k3", c->o.fix_k3, "estimate k3 too (default: fixed at 0)");
  add_detector_options(cal, c->det);
  cal->callback([c] {
    const video::CalibrationBoard board = video::make_aprilgrid(video::read_aprilgrid_spec(c->board));
    c->det.family = board.family;
    std::vector<std::string> names;
    std::vector<std::pair<int, std::string>> videos;
    for (const std::string& v : c->videos) {
      const auto [name, path] = video::parse_video_argument(v);
      videos.emplace_back(static_cast<int>(names.size()), path);
      names.push_back(name);
    }
    const std::vector<video::CameraFootage> footage = video::footage().detect_videos(videos, c->det, video::TagTrackerOptions{}, 30.0, 0, nullptr);
    c->o.world_from_reference_board.linear() =
        rotation_from_body_xyz(Eigen::Vector3d(c->xyz_deg[0], c->xyz_deg[1], c->xyz_deg[2]) * (M_PI / 180));
    c->o.world_from_reference_board.translation() = Eigen::Vector3d(c->position[0], c->position[1], c->position[2]);
    const video::CalibrationResult r = video::footage().calibrate_cameras(board, footage, names, c->o);
    write_text_atomic(c->out, video::format_calibration_json(r.rig));
    std::printf("%s\nwrote %s\n", r.summary.BriefReport().c_str(), c->out.c_str());
  });
}

// register-tags
void add_register_tags_command(CLI::App& app) {
  auto* reg = app.add_subcommand("register-tags",
                                 "Register a tag set on a static trial (the subject standing still), as OpenSim's MarkerPlacer:\n"
                                 "IK with the approximate tag poses, then each seen tag's pose on its body re-estimated from\n"
                                 "its triangulated corners. Writes the refined tag set JSON.");
  struct RegArgs {
    std::vector<std::string> videos;
    std::string calibration, tags, model, out;
  };
  auto g = std::make_shared<RegArgs>();
  reg->add_option("--videos", g->videos, "the static trial: one video per camera")->required();
  reg->add_option("--calibration", g->calibration, "camera calibration")->required()->check(CLI::ExistingFile);
  reg->add_option("--tags", g->tags, "approximate tag set (.json)")->required()->check(CLI::ExistingFile);
  reg->add_option("--model", g->model, "the subject's model (.osim)")->required()->check(CLI::ExistingFile);
  reg->add_option("-o,--output", g->out, "registered tag set (.json) to write")->required();
  reg->callback([g] {
    const video::CameraRig rig = video::read_calibration(g->calibration);
    const video::TagSet tags = video::read_tag_set(g->tags);
    const video::CaptureResult r = video::footage().capture_markers(rig, tags, g->videos, {}, nullptr);
    video::TagRegistrationSummary s;
    const video::TagSet out = video::register_tag_set(read_osim(g->model).model, tags, r.markers, {}, &s);
    write_text_atomic(g->out, video::format_tag_set_json(out));
    std::printf("%s\n%s\nwrote %s\n", r.summary.BriefReport().c_str(), s.BriefReport().c_str(), g->out.c_str());
  });
}

// capture
void add_capture_command(CLI::App& app) {
  auto* cap = app.add_subcommand("capture",
                                 "Turn AprilTag footage from calibrated cameras into virtual markers: detect tags in every\n"
                                 "video (in parallel), pair frames, triangulate each tag corner, and write a TRC (mm) with\n"
                                 "<output>_quality.sto (per frame and marker: reprojection error in px and cameras used) and\n"
                                 "<output>_markers.xml (the corners as an OpenSim MarkerSet, for `cpgait ik --marker-set`).");
  struct CapArgs {
    std::vector<std::string> videos;
    std::string calibration, tags, out, sync = "index";
    video::CaptureOptions o;
  };
  auto k = std::make_shared<CapArgs>();
  cap->add_option("--videos", k->videos, "one video per camera: NAME=PATH or a file named after its camera")->required();
  cap->add_option("--calibration", k->calibration, "camera calibration (.json, or OpenCV .yml/.xml)")->required()->check(CLI::ExistingFile);
  cap->add_option("--tags", k->tags, "tag set (.json): id -> body, size, pose on the body")->required()->check(CLI::ExistingFile);
  cap->add_option("-o,--output", k->out, "the .trc to write")->required();
  cap->add_option("--sync", k->sync, "pair frames by index, or by time with each camera's time_offset_s")
      ->check(CLI::IsMember({"index", "time"}))->capture_default_str();
  cap->add_option("--max-reprojection-px", k->o.triangulation.max_reprojection_error_px, "views above this error are dropped")
      ->capture_default_str();
  cap->add_option("--gap-fill-s", k->o.max_gap_fill_s, "fill gaps up to this long (s); 0: off")->capture_default_str();
  cap->add_flag("!--no-single-view", k->o.single_view_pose, "never place a tag from one camera's view (IPPE)");
  cap->add_option("--frame-rate", k->o.frame_rate_hz, "frames per second when a video does not say");
  cap->add_option("--threads", k->o.threads, "decoding threads (0: one per video)")->capture_default_str();
  add_detector_options(cap, k->o.detector);
  cap->callback([k] {
    const video::CameraRig rig = video::read_calibration(k->calibration);
    const video::TagSet tags = video::read_tag_set(k->tags);
    k->o.sync = k->sync == "time" ? video::CaptureOptions::Sync::kTime : video::CaptureOptions::Sync::kIndex;
    video::CaptureResult r = video::footage().capture_markers(rig, tags, k->videos, k->o, nullptr);
    r.markers.name = fs::path(k->out).filename().string();
    const std::string stem = (fs::path(k->out).parent_path() / fs::path(k->out).stem()).string();
    if (!fs::path(k->out).parent_path().empty()) ensure_directory(fs::path(k->out).parent_path().string());
    write_text_atomic(k->out, format_trc(r.markers, "mm"));
    write_storage_atomic(video::capture_quality_table(r), stem + "_quality.sto");
    write_text_atomic(stem + "_markers.xml", video::format_marker_set_xml(tags));
    for (const auto& w : r.summary.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    std::printf("%s\nwrote %s, %s_quality.sto, %s_markers.xml\n", r.summary.BriefReport().c_str(), k->out.c_str(), stem.c_str(),
                stem.c_str());
  });
}

}  // namespace

void add_video_commands(CLI::App& app) {
  add_detect_command(app);
  add_calibrate_command(app);
  add_register_tags_command(app);
  add_capture_command(app);
}

}  // namespace cpgait::services
