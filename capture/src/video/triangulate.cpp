#include "cpgait/video/triangulate.h"

#include <ceres/ceres.h>

#include <Eigen/SVD>
#include <cmath>

namespace cpgait::video {

Eigen::Vector3d triangulate_dlt(const CameraRig& rig, const std::vector<int>& cameras,
                                const std::vector<Eigen::Vector2d>& normalized) {
  Eigen::MatrixXd A(2 * static_cast<Eigen::Index>(cameras.size()), 4);
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = rig[static_cast<std::size_t>(cameras[i])];
    Eigen::Matrix<double, 3, 4> P;
    P << c.rotation_cam_from_world, c.translation_cam_from_world_m;
    const auto r = static_cast<Eigen::Index>(2 * i);
    A.row(r) = normalized[i].x() * P.row(2) - P.row(0);
    A.row(r + 1) = normalized[i].y() * P.row(2) - P.row(1);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  return X.head<3>() / X.w();
}

namespace {

struct ReprojectionCost {
  std::array<double, 9> intrinsics;
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  Eigen::Vector2d pixel;
  template <typename T>
  bool operator()(const T* X, T* residual) const {
    const Eigen::Matrix<T, 3, 1> p = R.cast<T>() * Eigen::Map<const Eigen::Matrix<T, 3, 1>>(X) + t.cast<T>();
    if (p.z() <= T(1e-6)) return false;
    std::array<T, 9> k;
    for (int i = 0; i < 9; ++i) k[static_cast<std::size_t>(i)] = T(intrinsics[static_cast<std::size_t>(i)]);
    const Eigen::Matrix<T, 2, 1> uv = project_camera_point(k.data(), p);
    residual[0] = uv.x() - T(pixel.x());
    residual[1] = uv.y() - T(pixel.y());
    return true;
  }
};

Eigen::Vector3d refine(const CameraRig& rig, const std::vector<PixelObservation>& obs, Eigen::Vector3d X) {
  ceres::Problem::Options po;
  po.enable_fast_removal = false;
  ceres::Problem problem(po);
  for (const PixelObservation& o : obs) {
    const Camera& c = rig[static_cast<std::size_t>(o.camera)];
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 3>(
                                 new ReprojectionCost{intrinsics_of(c), c.rotation_cam_from_world,
                                                      c.translation_cam_from_world_m, o.pixel}),
                             nullptr, X.data());
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 20;
  so.function_tolerance = 1e-10;
  so.parameter_tolerance = 1e-10;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  return X;
}

}  // namespace

TriangulatedPoint triangulate_point(const CameraRig& rig, const std::vector<PixelObservation>& observations,
                                    const TriangulationOptions& options) {
  TriangulatedPoint out;
  std::vector<PixelObservation> kept = observations;
  while (static_cast<int>(kept.size()) >= std::max(2, options.min_views)) {
    std::vector<int> cams;
    std::vector<Eigen::Vector2d> normalized;
    for (const PixelObservation& o : kept) {
      cams.push_back(o.camera);
      normalized.push_back(undistort_to_normalized(rig[static_cast<std::size_t>(o.camera)], o.pixel));
    }
    Eigen::Vector3d X = triangulate_dlt(rig, cams, normalized);
    if (!X.allFinite()) return out;
    if (options.refine) X = refine(rig, kept, X);
    double sum2 = 0, worst = -1;
    std::size_t worst_i = 0;
    for (std::size_t i = 0; i < kept.size(); ++i) {
      const double e = (project(rig[static_cast<std::size_t>(kept[i].camera)], X) - kept[i].pixel).norm();
      const double err = std::isfinite(e) ? e : 1e9;  // behind a camera: the worst possible view
      sum2 += err * err;
      if (err > worst) {
        worst = err;
        worst_i = i;
      }
    }
    if (worst <= options.max_reprojection_error_px) {
      out.position_m = X;
      out.rms_reprojection_px = std::sqrt(sum2 / static_cast<double>(kept.size()));
      out.views_used = static_cast<int>(kept.size());
      return out;
    }
    out.rejected_cameras.push_back(kept[worst_i].camera);
    kept.erase(kept.begin() + static_cast<long>(worst_i));
  }
  return out;
}

}  // namespace cpgait::video
