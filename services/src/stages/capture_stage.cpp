// Capture: AprilTag footage -> virtual markers (the tag corners), which the model gains as markers.
// Runs first, and only when the trial is footage.
#include "cpgait/video/tag_markers.h"
#include "cpgait/video/footage.h"
#include "stage.h"

namespace cpgait::services {
namespace {

struct CaptureStageOptions {
  // The capture library's defaults, so they are stated once.
  double max_reprojection_px = video::CaptureOptions{}.triangulation.max_reprojection_error_px;
  double gap_fill_s = video::CaptureOptions{}.max_gap_fill_s;
  bool single_view = video::CaptureOptions{}.single_view_pose;
  std::string sync = "index";
  double decimate = video::CaptureOptions{}.detector.quad_decimate;

  video::CaptureOptions capture_options() const {
    video::CaptureOptions c;
    c.triangulation.max_reprojection_error_px = max_reprojection_px;
    c.max_gap_fill_s = gap_fill_s;
    c.single_view_pose = single_view;
    c.sync = sync == "time" ? video::CaptureOptions::Sync::kTime : video::CaptureOptions::Sync::kIndex;
    c.detector.quad_decimate = static_cast<float>(decimate);
    return c;
  }

  static const OptionFields<CaptureStageOptions>& fields() {
    static const OptionFields<CaptureStageOptions> f =
        OptionFields<CaptureStageOptions>("Detection, triangulation and gap filling; footage trials only.")
            .number("max_reprojection_px", &CaptureStageOptions::max_reprojection_px, "px",
                    "a view whose reprojection error exceeds this is dropped", NumberRange{0.0, {}, true})
            .number("gap_fill_s", &CaptureStageOptions::gap_fill_s, "s", "longest gap filled by a cubic spline; 0: none",
                    NumberRange{0.0, 1.0})
            .boolean("single_view", &CaptureStageOptions::single_view, "corners of a tag seen by one camera from its IPPE pose")
            .choice("sync", &CaptureStageOptions::sync, {"index", "time"},
                    "index: frame i of every camera together; time: frames placed on the first camera's clock")
            .number("decimate", &CaptureStageOptions::decimate, "", "quad detection on the image decimated by this factor",
                    NumberRange{1.0, 8.0});
    return f;
  }
};

class CaptureStage final : public StageWithOptions<CaptureStageOptions> {
 public:
  std::string name() const override { return "capture"; }
  std::string description() const override { return "AprilTag capture: markers from the cameras' footage"; }
  std::vector<std::string> writes() const override { return {".trc", "_capture_quality.sto", "_tag_markers.xml"}; }
  std::vector<std::string> tables() const override { return {"_capture_quality.sto"}; }
  bool applies(const TrialInputs& in) const override { return in.has_footage(); }
  bool selectable() const override { return false; }

 protected:
  void check(const StageContext& trial, const CaptureStageOptions&) const override {
    const TrialInputs& in = trial.inputs;
    const video::CameraRig rig = video::read_calibration(in.calibration_path);
    const video::TagSet tags = video::read_tag_set(in.tags_path);
    video::with_tag_markers(trial.model, tags, in.tags_path);
    for (const auto& [camera, path] : video::match_videos_to_cameras(rig, in.videos)) video::footage().probe_video(path);
  }
  nlohmann::json execute(StageContext& trial, const CaptureStageOptions& o) const override {
    const TrialInputs& in = trial.inputs;
    const video::CameraRig rig = video::read_calibration(in.calibration_path);
    const video::TagSet tags = video::read_tag_set(in.tags_path);
    trial.model = video::with_tag_markers(trial.model, tags, in.tags_path);
    video::CaptureResult r = video::footage().capture_markers(rig, tags, in.videos, o.capture_options(), trial.progress);
    r.markers.name = in.name + ".trc";
    trial.write_text(format_trc(r.markers, "mm"), ".trc");
    trial.write(video::capture_quality_table(r), "_capture_quality.sto");
    trial.write_text(video::format_marker_set_xml(tags), "_tag_markers.xml");
    trial.markers = std::move(r.markers);
    const auto& cs = r.summary;
    return {{"frames", cs.num_frames},
            {"cameras", cs.cameras},
            {"frames_per_second", cs.detect_seconds > 0 ? cs.num_frames * static_cast<double>(cs.cameras.size()) / cs.detect_seconds : 0.0},
            {"corners_triangulated", cs.corners_triangulated},
            {"corners_single_view", cs.corners_single_view},
            {"corners_gap_filled", cs.corners_filled},
            {"corners_missing", cs.corners_missing},
            {"views_rejected", cs.views_rejected},
            {"median_reprojection_px", cs.median_reprojection_px},
            {"warnings", cs.warnings}};
  }
};

}  // namespace

const Stage& capture_stage() {
  static const CaptureStage stage;
  return stage;
}

}  // namespace cpgait::services
