// AprilTag capture on one thread: tag detection in frames/s per 1280x720 camera (rendered walking
// footage, decoded into memory first so only detection is timed), with the detector settings named
// in each benchmark; and triangulation in frames/s for four cameras.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "cpgait/fixtures/tag_footage.h"
#include "cpgait/video/capture_markers.h"
#include "cpgait/video/tag_tracker.h"

using namespace cpgait;

namespace {
struct Footage {
  fixtures::WalkFootage walk;
  std::vector<cv::Mat> frames;  // camera 0, grey
};
const Footage& footage() {
  static const Footage f = [] {
    Footage out;
    const std::string dir = (std::filesystem::temp_directory_path() / "cpgait_bench_footage").string();
    fixtures::FootageOptions o;
    o.render.blur_samples = 3;
    o.render.exposure_s = 1.0 / 500;
    out.walk = fixtures::render_walk_footage(dir, o);
    cv::VideoCapture v(out.walk.videos[0], cv::CAP_FFMPEG);
    cv::Mat frame, grey;
    while (v.read(frame)) {
      cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
      out.frames.push_back(grey.clone());
    }
    return out;
  }();
  return f;
}

void detect_frames(benchmark::State& state, float decimate, bool region_pass) {
  const Footage& f = footage();
  video::TagDetectorOptions o;
  o.quad_decimate = decimate;
  video::TagTrackerOptions t;
  t.region_pass = region_pass;
  long frames = 0, tags = 0;
  for (auto _ : state) {
    video::TagTracker tracker(o, t);
    for (const cv::Mat& img : f.frames) {
      tags += static_cast<long>(tracker.detect(img).size());
      ++frames;
    }
  }
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsRate);
  state.counters["tags/frame"] = static_cast<double>(tags) / static_cast<double>(frames);
}
}  // namespace

// The capture default: quads on a 3x decimated image, then full resolution over the subject's region.
static void BM_DetectTags720p_Default(benchmark::State& state) { detect_frames(state, 3.0f, true); }
// Full resolution everywhere (the most thorough, the slowest).
static void BM_DetectTags720p_FullResolution(benchmark::State& state) { detect_frames(state, 1.0f, false); }
// Decimated pass only (fastest; misses small tags).
static void BM_DetectTags720p_Decimate2Only(benchmark::State& state) { detect_frames(state, 2.0f, false); }
BENCHMARK(BM_DetectTags720p_Default)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK(BM_DetectTags720p_FullResolution)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK(BM_DetectTags720p_Decimate2Only)->Unit(benchmark::kMillisecond)->Iterations(2);

static void BM_TriangulateFourCameras(benchmark::State& state) {
  const Footage& f = footage();
  const video::CameraRig rig = video::read_calibration(f.walk.calibration_path);
  const video::TagSet tags = video::read_tag_set(f.walk.tags_path);
  std::vector<video::CameraFootage> detected;
  for (std::size_t c = 0; c < f.walk.videos.size(); ++c) detected.push_back(video::detect_video(static_cast<int>(c), f.walk.videos[c], {}));
  long frames = 0;
  for (auto _ : state) {
    const video::CaptureResult r = video::triangulate_footage(rig, tags, detected);
    frames += r.summary.num_frames;
  }
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_TriangulateFourCameras)->Unit(benchmark::kMillisecond)->MinTime(1.0);
