#include "cpgait/dynamics/applied_loads.h"

#include <algorithm>

#include "cpgait/capture/input_error.h"

namespace cpgait {

AppliedLoads::AppliedLoads(const Model& model, const ExternalLoadsSpec& spec, const Storage& data) : data_(data) {
  if (data.num_rows() < 1) throw InputError(spec.file, 0, "datafile", "the load data file has no rows");
  auto body = [&](const ExternalForceSpec& e, const std::string& name, const char* field) {
    const int b = name == "ground" ? 0 : model.body_index(name);
    if (b < 0) throw InputError(spec.file, e.line, field, "body '" + name + "' is not in the model");
    return b;
  };
  // OpenSim's rule: the first three columns whose labels begin with the identifier, in file order
  // (ground_force_v -> ground_force_vx/vy/vz, ground_torque -> ground_torque_x/_y/_z).
  auto columns = [&](const ExternalForceSpec& e, const std::string& prefix, const char* field) {
    std::array<int, 3> c{-1, -1, -1};
    if (prefix.empty()) return c;
    int found = 0;
    for (int k = 1; k < data.num_columns() && found < 3; ++k)
      if (data.labels[k].compare(0, prefix.size(), prefix) == 0) c[found++] = k;
    if (found < 3)
      throw InputError(spec.file, e.line, field,
                       "the data file has " + std::to_string(found) + " column(s) beginning with '" + prefix + "'; 3 are needed (x, y, z)");
    return c;
  };
  for (const auto& e : spec.forces) {
    forces_.push_back({body(e, e.applied_to_body, "applied_to_body"),
                       body(e, e.force_expressed_in_body, "force_expressed_in_body"),
                       body(e, e.point_expressed_in_body, "point_expressed_in_body"),
                       columns(e, e.force_identifier, "force_identifier"),
                       columns(e, e.point_identifier, "point_identifier"),
                       columns(e, e.torque_identifier, "torque_identifier")});
  }
}

double AppliedLoads::start_time_s() const { return data_.time()[0]; }
double AppliedLoads::end_time_s() const { return data_.time()[data_.num_rows() - 1]; }

void AppliedLoads::forces_at(double t, const KinematicsWorkspace<double>& kin, std::vector<Sample>& out) const {
  out.clear();
  const auto time = data_.time();
  const int n = data_.num_rows();
  // Linear interpolation; held at the end values outside the data.
  const int hi = static_cast<int>(std::upper_bound(time.data(), time.data() + n, t) - time.data());
  const int i1 = std::clamp(hi, 0, n - 1), i0 = std::clamp(hi - 1, 0, n - 1);
  const double span = time[i1] - time[i0];
  const double a = span > 0 ? std::clamp((t - time[i0]) / span, 0.0, 1.0) : 0.0;
  auto vec = [&](const std::array<int, 3>& cols) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v[k] = (1 - a) * data_.data(i0, cols[k]) + a * data_.data(i1, cols[k]);
    return v;
  };
  for (const Force& f : forces_) {
    Sample s{f.body, kin.body_in_ground[f.body].translation_m, vec(f.force_cols), Eigen::Vector3d::Zero()};
    if (f.force_frame != 0) s.force_N = kin.body_in_ground[f.force_frame].rotation * s.force_N;
    if (f.point_cols[0] >= 0) {  // else the body origin
      s.point_m = vec(f.point_cols);
      if (f.point_frame != 0) {
        const auto& P = kin.body_in_ground[f.point_frame];
        s.point_m = P.rotation * s.point_m + P.translation_m;
      }
    }
    // Free torques are expressed like the force.
    if (f.torque_cols[0] >= 0) {
      s.torque_Nm = vec(f.torque_cols);
      if (f.force_frame != 0) s.torque_Nm = kin.body_in_ground[f.force_frame].rotation * s.torque_Nm;
    }
    out.push_back(s);
  }
}

void AppliedLoads::wrenches_at(double t, const KinematicsWorkspace<double>& kin, std::vector<Vector6d>& out) const {
  for (auto& w : out) w.setZero();
  thread_local std::vector<Sample> samples;
  forces_at(t, kin, samples);
  for (const Sample& s : samples) out[s.body] += spatial_force(s.force_N, s.point_m, s.torque_Nm);
}

}  // namespace cpgait
