#pragma once
// OpenSim's `orientation` convention, used by its documents and by cpgait's tag sets.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace cpgait {

// Rotation of body-fixed X-Y-Z Euler angles (rad).
inline Eigen::Matrix3d rotation_from_body_xyz(const Eigen::Vector3d& a) {
  return (Eigen::AngleAxisd(a.x(), Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(a.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(a.z(), Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

}  // namespace cpgait
