#include "cpgait/video/calibrate_cameras.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <chrono>
#include <cmath>
#include <map>
#include <opencv2/calib3d.hpp>
#include <sstream>

#include "cpgait/capture/input_error.h"

namespace cpgait::video {

namespace {

using Pose6 = std::array<double, 6>;  // angle-axis, translation: p_out = R p_in + t

Pose6 to_pose6(const Eigen::Isometry3d& X) {
  const Eigen::AngleAxisd aa(X.linear());
  const Eigen::Vector3d r = aa.angle() * aa.axis();
  return {r.x(), r.y(), r.z(), X.translation().x(), X.translation().y(), X.translation().z()};
}

Eigen::Isometry3d from_pose6(const Pose6& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d r(p[0], p[1], p[2]);
  if (r.norm() > 0) X.linear() = Eigen::AngleAxisd(r.norm(), r.normalized()).toRotationMatrix();
  X.translation() = Eigen::Vector3d(p[3], p[4], p[5]);
  return X;
}

Eigen::Isometry3d from_rvec_tvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  return from_pose6({rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2), tvec.at<double>(0), tvec.at<double>(1),
                     tvec.at<double>(2)});
}

struct BoardCornerCost {
  Eigen::Vector3d corner_in_board;
  Eigen::Vector2d pixel;
  template <typename T>
  bool operator()(const T* intrinsics, const T* cam_from_world, const T* world_from_board, T* residual) const {
    const T X[3] = {T(corner_in_board.x()), T(corner_in_board.y()), T(corner_in_board.z())};
    T w[3], c[3];
    ceres::AngleAxisRotatePoint(world_from_board, X, w);
    for (int i = 0; i < 3; ++i) w[i] += world_from_board[3 + i];
    ceres::AngleAxisRotatePoint(cam_from_world, w, c);
    for (int i = 0; i < 3; ++i) c[i] += cam_from_world[3 + i];
    if (c[2] <= T(1e-6)) return false;
    const Eigen::Matrix<T, 2, 1> uv = project_camera_point(intrinsics, Eigen::Matrix<T, 3, 1>(c[0], c[1], c[2]));
    residual[0] = uv.x() - T(pixel.x());
    residual[1] = uv.y() - T(pixel.y());
    return true;
  }
};

struct Observation {
  int camera;
  int frame;
  Eigen::Vector3d corner_in_board;
  Eigen::Vector2d pixel;
};

}  // namespace

CalibrationResult calibrate_cameras(const CalibrationBoard& board, const std::vector<CameraFootage>& footage,
                                    const std::vector<std::string>& names, const CalibrationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const int C = static_cast<int>(footage.size());
  if (C == 0) throw InputError("calibration", 0, "videos", "no footage given");
  int F = 0;
  for (const CameraFootage& f : footage) F = std::max(F, static_cast<int>(f.frames.size()));

  // Board views per camera: frame -> the detections of board tags (on the face seen most).
  std::vector<std::map<int, std::vector<const TagDetection*>>> views(static_cast<std::size_t>(C));
  for (int c = 0; c < C; ++c)
    for (int i = 0; i < static_cast<int>(footage[static_cast<std::size_t>(c)].frames.size()); ++i) {
      std::map<int, std::vector<const TagDetection*>> by_face;
      for (const TagDetection& d : footage[static_cast<std::size_t>(c)].frames[static_cast<std::size_t>(i)])
        if (const BoardTag* t = board.find(d.id)) by_face[t->face].push_back(&d);
      const std::vector<const TagDetection*>* best = nullptr;
      for (const auto& [face, ds] : by_face)
        if (!best || ds.size() > best->size()) best = &ds;
      if (best && static_cast<int>(best->size()) >= options.min_tags_per_view) views[static_cast<std::size_t>(c)][i] = *best;
    }

  CalibrationResult result;
  std::vector<std::array<double, 9>> intrinsics(static_cast<std::size_t>(C));
  std::vector<std::map<int, Eigen::Isometry3d>> cam_from_board(static_cast<std::size_t>(C));
  for (int c = 0; c < C; ++c) {
    const CameraFootage& f = footage[static_cast<std::size_t>(c)];
    const std::string& name = names[static_cast<std::size_t>(f.camera)];
    const auto& v = views[static_cast<std::size_t>(c)];
    if (v.size() < 3)
      throw InputError(f.source, 0, "videos", "camera " + name + " sees the board (" + std::to_string(options.min_tags_per_view) +
                                                  "+ tags) in only " + std::to_string(v.size()) + " frames; at least 3 needed");
    // calibrateCamera wants planar object points with z = 0: use each view's face frame.
    std::vector<std::vector<cv::Point3f>> object;
    std::vector<std::vector<cv::Point2f>> image;
    std::vector<int> frames, faces;
    for (const auto& [frame, ds] : v) {
      const int face = board.find(ds.front()->id)->face;
      const Eigen::Isometry3d face_from_board = board.board_from_face[static_cast<std::size_t>(face)].inverse();
      std::vector<cv::Point3f> o;
      std::vector<cv::Point2f> p;
      for (const TagDetection* d : ds)
        for (int k = 0; k < 4; ++k) {
          const Eigen::Vector3d X = face_from_board * board.corner_in_board_m(*board.find(d->id), k);
          o.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()), 0.0f);
          p.emplace_back(static_cast<float>(d->corners_px[static_cast<std::size_t>(k)].x()),
                         static_cast<float>(d->corners_px[static_cast<std::size_t>(k)].y()));
        }
      object.push_back(o);
      image.push_back(p);
      frames.push_back(frame);
      faces.push_back(face);
    }
    cv::Mat K, dist;
    std::vector<cv::Mat> rvecs, tvecs;
    const int flags = options.fix_k3 ? cv::CALIB_FIX_K3 : 0;
    double rms = 0;
    try {
      rms = cv::calibrateCamera(object, image, cv::Size(f.width_px, f.height_px), K, dist, rvecs, tvecs, flags);
    } catch (const cv::Exception& e) {
      throw InputError(f.source, 0, "videos", "calibration of camera " + name + " failed: " + e.what());
    }
    intrinsics[static_cast<std::size_t>(c)] = {K.at<double>(0, 0), K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2),
                                               dist.at<double>(0), dist.at<double>(1), dist.at<double>(2), dist.at<double>(3),
                                               dist.total() > 4 ? dist.at<double>(4) : 0.0};
    for (std::size_t k = 0; k < frames.size(); ++k)
      cam_from_board[static_cast<std::size_t>(c)][frames[k]] =
          from_rvec_tvec(rvecs[k], tvecs[k]) * board.board_from_face[static_cast<std::size_t>(faces[k])].inverse();
    CameraCalibrationReport report;
    report.name = name;
    report.views = static_cast<int>(frames.size());
    report.single_camera_rms_px = rms;
    result.summary.cameras.push_back(report);
  }

  // Chain extrinsics through shared board views, starting from the reference frame.
  int ref = options.reference_frame;
  if (ref < 0) {
    int most = 0;
    for (int i = 0; i < F; ++i) {
      int n = 0;
      for (int c = 0; c < C; ++c) n += cam_from_board[static_cast<std::size_t>(c)].count(i) > 0;
      if (n > most) {
        most = n;
        ref = i;
      }
    }
  }
  if (ref < 0 || ref >= F) throw InputError("calibration", 0, "reference_frame", "no frame shows the board");
  std::vector<std::optional<Eigen::Isometry3d>> cam_from_world(static_cast<std::size_t>(C));
  std::vector<std::optional<Eigen::Isometry3d>> world_from_board(static_cast<std::size_t>(F));
  world_from_board[static_cast<std::size_t>(ref)] = options.world_from_reference_board;
  for (bool changed = true; changed;) {
    changed = false;
    for (int c = 0; c < C; ++c)
      for (const auto& [frame, X_cb] : cam_from_board[static_cast<std::size_t>(c)]) {
        auto& wb = world_from_board[static_cast<std::size_t>(frame)];
        auto& cw = cam_from_world[static_cast<std::size_t>(c)];
        if (wb && !cw) {
          cw = X_cb * wb->inverse();
          changed = true;
        } else if (cw && !wb) {
          wb = cw->inverse() * X_cb;
          changed = true;
        }
      }
  }
  for (int c = 0; c < C; ++c)
    if (!cam_from_world[static_cast<std::size_t>(c)])
      throw InputError(footage[static_cast<std::size_t>(c)].source, 0, "videos",
                       "camera " + names[static_cast<std::size_t>(footage[static_cast<std::size_t>(c)].camera)] +
                           " never sees the board in a frame another calibrated camera sees; its pose cannot be chained");

  // Joint bundle adjustment.
  std::vector<Pose6> cam_pose(static_cast<std::size_t>(C));
  std::vector<Pose6> board_pose(static_cast<std::size_t>(F));
  for (int c = 0; c < C; ++c) cam_pose[static_cast<std::size_t>(c)] = to_pose6(*cam_from_world[static_cast<std::size_t>(c)]);
  for (int i = 0; i < F; ++i)
    if (world_from_board[static_cast<std::size_t>(i)]) board_pose[static_cast<std::size_t>(i)] = to_pose6(*world_from_board[static_cast<std::size_t>(i)]);
  std::vector<Observation> obs;
  for (int c = 0; c < C; ++c)
    for (const auto& [frame, ds] : views[static_cast<std::size_t>(c)]) {
      if (!world_from_board[static_cast<std::size_t>(frame)]) continue;
      for (const TagDetection* d : ds)
        for (int k = 0; k < 4; ++k)
          obs.push_back({c, frame, board.corner_in_board_m(*board.find(d->id), k), d->corners_px[static_cast<std::size_t>(k)]});
    }
  ceres::Problem problem;
  for (const Observation& o : obs)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<BoardCornerCost, 2, 9, 6, 6>(new BoardCornerCost{o.corner_in_board, o.pixel}),
                             new ceres::HuberLoss(options.huber_loss_px), intrinsics[static_cast<std::size_t>(o.camera)].data(),
                             cam_pose[static_cast<std::size_t>(o.camera)].data(), board_pose[static_cast<std::size_t>(o.frame)].data());
  problem.SetParameterBlockConstant(board_pose[static_cast<std::size_t>(ref)].data());
  if (options.fix_k3)
    for (auto& k : intrinsics) problem.SetManifold(k.data(), new ceres::SubsetManifold(9, {8}));
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  // Results and per-camera errors.
  std::vector<double> sum2(static_cast<std::size_t>(C), 0.0);
  std::vector<int> count(static_cast<std::size_t>(C), 0);
  double total2 = 0;
  for (const Observation& o : obs) {
    double r[2];
    BoardCornerCost{o.corner_in_board, o.pixel}(intrinsics[static_cast<std::size_t>(o.camera)].data(),
                                                cam_pose[static_cast<std::size_t>(o.camera)].data(),
                                                board_pose[static_cast<std::size_t>(o.frame)].data(), r);
    sum2[static_cast<std::size_t>(o.camera)] += r[0] * r[0] + r[1] * r[1];
    ++count[static_cast<std::size_t>(o.camera)];
    total2 += r[0] * r[0] + r[1] * r[1];
  }
  for (int c = 0; c < C; ++c) {
    const CameraFootage& f = footage[static_cast<std::size_t>(c)];
    const auto& k = intrinsics[static_cast<std::size_t>(c)];
    Camera cam;
    cam.name = names[static_cast<std::size_t>(f.camera)];
    cam.width_px = f.width_px;
    cam.height_px = f.height_px;
    cam.fx_px = k[0];
    cam.fy_px = k[1];
    cam.cx_px = k[2];
    cam.cy_px = k[3];
    cam.distortion = {k[4], k[5], k[6], k[7], k[8]};
    const Eigen::Isometry3d X = from_pose6(cam_pose[static_cast<std::size_t>(c)]);
    cam.rotation_cam_from_world = X.linear();
    cam.translation_cam_from_world_m = X.translation();
    result.rig.push_back(cam);
    result.summary.cameras[static_cast<std::size_t>(c)].rms_px =
        count[static_cast<std::size_t>(c)] ? std::sqrt(sum2[static_cast<std::size_t>(c)] / count[static_cast<std::size_t>(c)]) : 0;
  }
  result.world_from_board.resize(static_cast<std::size_t>(F));
  for (int i = 0; i < F; ++i)
    if (world_from_board[static_cast<std::size_t>(i)]) {
      result.world_from_board[static_cast<std::size_t>(i)] = from_pose6(board_pose[static_cast<std::size_t>(i)]);
      ++result.summary.board_poses;
    }
  result.summary.observations = static_cast<int>(obs.size());
  result.summary.rms_px = obs.empty() ? 0 : std::sqrt(total2 / static_cast<double>(obs.size()));
  result.summary.iterations = static_cast<int>(summary.iterations.size());
  result.summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace cpgait::video
