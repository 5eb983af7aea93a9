#include "cpgait/muscles/muscle_analysis.h"

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "cpgait/dynamics/coordinate_couplers.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/muscles/muscle_model.h"
#include "cpgait/muscles/muscle_path.h"

namespace cpgait {

std::string MuscleAnalysisSummary::BriefReport() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "muscle analysis: %d frames x %d muscles (%d wrapping) in %.3f s (%.0f frames/s)", frames,
                muscles, wrapping_muscles, solve_seconds, frames_per_second());
  return buf;
}

MuscleAnalysisResult muscle_analysis(const Model& model, const CoordinateTrajectories& kinematics,
                                     const MuscleAnalysisOptions& options) {
  std::vector<int> coords;
  for (const auto& name : options.moment_arm_coordinates) {
    const int c = model.coordinate_index(name);
    if (c < 0) throw std::invalid_argument("moment_arm_coordinate_list names '" + name + "', which the model does not have");
    coords.push_back(c);
  }
  const int step = std::max(1, options.step_interval);
  const int nm = static_cast<int>(model.muscles.size());
  std::vector<int> rows;
  for (int i = 0; i < static_cast<int>(kinematics.time_s.size()); i += step) rows.push_back(i);
  MuscleAnalysisResult r;
  r.length_m.resize(rows.size(), nm);
  r.lengthening_speed_m_s.resize(rows.size(), nm);
  r.moment_arm_m.assign(coords.size(), Eigen::MatrixXd(rows.size(), nm));
  if (options.activation) {
    if (options.activation->rows() != static_cast<Eigen::Index>(kinematics.time_s.size()) || options.activation->cols() != nm)
      throw std::invalid_argument("muscle_analysis: one activation per sample and muscle is needed");
    r.fiber_length_m.resize(rows.size(), nm);
  }
  const auto t0 = std::chrono::steady_clock::now();
  KinematicsWorkspace<double> ws(model);
  MotionSubspace S(model);
  MusclePathGeometry g(model);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    Eigen::VectorXd q = kinematics.q.row(rows[k]).transpose(), qd = kinematics.qd.row(rows[k]).transpose();
    // The state on its constraints, as OpenSim's AnalyzeTool assembles each one.
    assemble_coordinate_constraints(model, q.data(), qd.data());
    forward_kinematics(model, q.data(), ws);
    motion_subspace(model, q.data(), ws, S);
    muscle_path_geometry(model, q.data(), qd.data(), ws, S, g);
    r.time_s.push_back(kinematics.time_s[rows[k]]);
    r.length_m.row(k) = g.length_m.transpose();
    r.lengthening_speed_m_s.row(k) = g.lengthening_speed_m_s.transpose();
    for (std::size_t c = 0; c < coords.size(); ++c) r.moment_arm_m[c].row(k) = g.moment_arm_m.col(coords[c]).transpose();
    if (options.activation)
      for (int m = 0; m < nm; ++m)
        r.fiber_length_m(k, m) = muscles::isometric_fiber_length(model.muscles[m], (*options.activation)(rows[k], m), g.length_m[m]);
  }
  r.summary.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.summary.frames = static_cast<int>(rows.size());
  r.summary.muscles = nm;
  for (const auto& mu : model.muscles) r.summary.wrapping_muscles += mu.wraps.empty() ? 0 : 1;
  return r;
}

}  // namespace cpgait
