#pragma once
// External loads (ground reaction forces) resolved against a model and a data table: per frame,
// the spatial force each body receives.
#include <Eigen/Core>
#include <array>
#include <vector>

#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/storage.h"
#include "cpgait/dynamics/rnea.h"
#include "cpgait/model/model.h"

namespace cpgait {

class AppliedLoads {
 public:
  // Throws InputError naming the XML line when a body or a data column is missing.
  AppliedLoads(const Model& model, const ExternalLoadsSpec& spec, const Storage& data);

  // Each external force at time t, in ground: the body it acts on, where, how much.
  struct Sample {
    int body;
    Eigen::Vector3d point_m, force_N, torque_Nm;
  };
  void forces_at(double t_s, const KinematicsWorkspace<double>& kinematics, std::vector<Sample>& out) const;
  // Spatial forces (ground, about the ground origin) per body at time t, data interpolated linearly.
  // `kinematics` gives body poses for forces or points expressed in a body frame.
  void wrenches_at(double t_s, const KinematicsWorkspace<double>& kinematics, std::vector<Vector6d>& out) const;

  int num_forces() const { return static_cast<int>(forces_.size()); }
  double start_time_s() const;
  double end_time_s() const;

 private:
  struct Force {
    int body, force_frame, point_frame;  // body indices; 0 = ground
    std::array<int, 3> force_cols, point_cols, torque_cols;  // x, y, z columns; [0] is -1 when absent
  };
  std::vector<Force> forces_;
  Storage data_;
};

}  // namespace cpgait
