#pragma once
// OpenSim's MuscleAnalysis for a coordinate trajectory: each muscle's musculotendon length,
// lengthening speed and moment arms about chosen coordinates at every sample. It is how OpenSim users
// check a model's paths, wrapping included.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/model/model.h"

namespace cpgait {

struct MuscleAnalysisOptions {
  // Coordinates whose moment arms are reported (names); none when empty.
  std::vector<std::string> moment_arm_coordinates;
  // Every step_interval-th sample of the trajectory (OpenSim's step_interval; default 1).
  int step_interval = 1;
  // Activation per trajectory sample and muscle (rows as the trajectory's; nullptr: none). Given, the
  // fibre lengths reported are each muscle's isometric equilibrium at it (OpenSim's
  // solve_for_equilibrium_for_auxiliary_states).
  const Eigen::MatrixXd* activation = nullptr;
};

struct MuscleAnalysisSummary {
  int frames = 0;
  int muscles = 0;
  int wrapping_muscles = 0;  // muscles whose path names a wrapping surface
  double solve_seconds = 0;
  double frames_per_second() const { return solve_seconds > 0 ? frames / solve_seconds : 0; }
  std::string BriefReport() const;
};

struct MuscleAnalysisResult {
  std::vector<double> time_s;
  Eigen::MatrixXd length_m;               // frames x muscles
  Eigen::MatrixXd lengthening_speed_m_s;  // frames x muscles
  std::vector<Eigen::MatrixXd> moment_arm_m;  // per requested coordinate: frames x muscles (m, or m/m)
  Eigen::MatrixXd fiber_length_m;             // frames x muscles, with an activation given; else empty
  MuscleAnalysisSummary summary;
};

// Throws std::invalid_argument naming a requested coordinate the model lacks.
MuscleAnalysisResult muscle_analysis(const Model& model, const CoordinateTrajectories& kinematics,
                                     const MuscleAnalysisOptions& options);

}  // namespace cpgait
