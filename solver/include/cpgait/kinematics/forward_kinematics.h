#pragma once
// Forward kinematics over the model's tree, on any scalar (double, or ceres::Jet so Ceres
// differentiates through it exactly). No allocation once the workspace has its size.
#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

template <typename T>
struct PoseT {
  Eigen::Matrix<T, 3, 3> rotation;
  Eigen::Matrix<T, 3, 1> translation_m;
};

template <typename T>
struct KinematicsWorkspace {
  std::vector<PoseT<T>> body_in_ground;  // X_GB for every body; [0] is ground
  explicit KinematicsWorkspace(const Model& m) : body_in_ground(m.bodies.size()) {}
};

// Rotation by angle about a unit axis (Rodrigues).
template <typename T>
Eigen::Matrix<T, 3, 3> axis_rotation(const Eigen::Vector3d& a, const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle), v = T(1.0) - c;
  Eigen::Matrix<T, 3, 3> R;
  R(0, 0) = c + v * a.x() * a.x();
  R(1, 1) = c + v * a.y() * a.y();
  R(2, 2) = c + v * a.z() * a.z();
  R(0, 1) = v * a.x() * a.y() - s * a.z();
  R(1, 0) = v * a.x() * a.y() + s * a.z();
  R(0, 2) = v * a.x() * a.z() + s * a.y();
  R(2, 0) = v * a.x() * a.z() - s * a.y();
  R(1, 2) = v * a.y() * a.z() - s * a.x();
  R(2, 1) = v * a.y() * a.z() + s * a.x();
  return R;
}

// The value of a transform axis' function at the current coordinates.
template <typename T>
T axis_value(const TransformAxis& ax, const T* q) {
  return ax.coordinate >= 0 ? ax.function.value(q[ax.coordinate]) : T(ax.function.value(0.0));
}

// X_FM: rotations applied body-fixed in order rotation1..3, then translation along axes of F. Scaled
// (kScaled, with the parent body's factors), translations that are not the coordinate itself are
// scaled along their axis, as scale_model scales them; the unscaled instance is the plain one.
template <typename T, bool kScaled = false>
PoseT<T> joint_transform(const Joint& j, const T* q, const Eigen::Matrix<T, 3, 1>* parent_scale = nullptr) {
  PoseT<T> X;
  X.rotation.setIdentity();
  for (int s = 0; s < 3; ++s) {
    const TransformAxis& ax = j.axes[s];
    if (ax.coordinate < 0 && ax.function.value(0.0) == 0.0) continue;
    X.rotation = (X.rotation * axis_rotation(ax.axis, axis_value(ax, q))).eval();
  }
  X.translation_m.setZero();
  for (int s = 3; s < 6; ++s) {
    const TransformAxis& ax = j.axes[s];
    if (ax.coordinate < 0 && ax.function.value(0.0) == 0.0) continue;
    if constexpr (kScaled) {
      if (!ax.function.is_identity()) {
        const Eigen::Matrix<T, 3, 1> a = ax.axis.cast<T>();
        X.translation_m += a * (axis_value(ax, q) * a.dot(*parent_scale));
        continue;
      }
    }
    X.translation_m += ax.axis.cast<T>() * axis_value(ax, q);
  }
  return X;
}

namespace detail {
template <typename T, bool kScaled>
void forward_kinematics(const Model& model, const T* q, KinematicsWorkspace<T>& ws, const Eigen::Matrix<T, 3, 1>* body_scale) {
  auto& X = ws.body_in_ground;
  X[0].rotation.setIdentity();
  X[0].translation_m.setZero();
  for (const Joint& j : model.joints) {
    const PoseT<T>& P = X[j.parent_body];
    const PoseT<T> FM = joint_transform<T, kScaled>(j, q, kScaled ? &body_scale[j.parent_body] : nullptr);
    // X_GF = X_GP * X_PF (the unscaled instance keeps the offsets as expressions: no Jet copies)
    const Eigen::Matrix<T, 3, 3> R_GF = P.rotation * j.parent_offset.rotation.cast<T>();
    const Eigen::Matrix<T, 3, 1> p_GF = [&] {
      if constexpr (kScaled)
        return Eigen::Matrix<T, 3, 1>(P.rotation * j.parent_offset.translation_m.cast<T>().cwiseProduct(body_scale[j.parent_body]) +
                                      P.translation_m);
      else
        return Eigen::Matrix<T, 3, 1>(P.rotation * j.parent_offset.translation_m.cast<T>() + P.translation_m);
    }();
    // X_GM = X_GF * X_FM; X_GB = X_GM * X_MB with X_MB = inverse(child_offset).
    const Eigen::Matrix<T, 3, 3> R_GM = R_GF * FM.rotation;
    const Eigen::Matrix<T, 3, 1> p_GM = R_GF * FM.translation_m + p_GF;
    const Eigen::Matrix3d R_BM = j.child_offset.rotation;
    PoseT<T>& C = X[j.child_body];
    C.rotation = R_GM * R_BM.transpose().cast<T>();
    if constexpr (kScaled)
      C.translation_m = p_GM - C.rotation * j.child_offset.translation_m.cast<T>().cwiseProduct(body_scale[j.child_body]);
    else
      C.translation_m = p_GM - C.rotation * j.child_offset.translation_m.cast<T>();
  }
}
}  // namespace detail

template <typename T>
void forward_kinematics(const Model& model, const T* q, KinematicsWorkspace<T>& ws) {
  detail::forward_kinematics<T, false>(model, q, ws, nullptr);
}

// The model placed as scale_model would scale it with one factor triple per body (joint frames by
// their body's factors), on any scalar so that the factors can be differentiated too.
template <typename T>
void scaled_forward_kinematics(const Model& model, const T* q, const Eigen::Matrix<T, 3, 1>* body_scale, KinematicsWorkspace<T>& ws) {
  detail::forward_kinematics<T, true>(model, q, ws, body_scale);
}

template <typename T>
Eigen::Matrix<T, 3, 1> marker_position(const Model& model, int marker, const KinematicsWorkspace<T>& ws) {
  const Marker& mk = model.markers[marker];
  const PoseT<T>& B = ws.body_in_ground[mk.body];
  return B.rotation * mk.location_m.cast<T>() + B.translation_m;
}

// The whole body's centre of mass (m, ground frame) in the pose ws holds.
inline Eigen::Vector3d centre_of_mass_m(const Model& model, const KinematicsWorkspace<double>& ws) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double mass = 0;
  for (std::size_t b = 1; b < model.bodies.size(); ++b) {
    c += model.bodies[b].mass_kg * (ws.body_in_ground[b].rotation * model.bodies[b].com_m + ws.body_in_ground[b].translation_m);
    mass += model.bodies[b].mass_kg;
  }
  return mass > 0 ? Eigen::Vector3d(c / mass) : c;
}

}  // namespace cpgait
