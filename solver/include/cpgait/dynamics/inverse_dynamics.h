#pragma once
// The inverse dynamics stage, as OpenSim's ID tool: coordinates from a .mot/.sto, optionally
// low-pass filtered, differentiated, then RNEA with external loads at each sample in the range.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/model/model.h"
#include "cpgait/progress.h"

namespace cpgait {

struct InverseDynamicsOptions {
  // Low-pass cutoff for the coordinates (Hz); negative: no filtering (OpenSim's default). Filtering
  // is OpenSim's: pad by half the length with an odd reflection, then a zero-phase third-order
  // Butterworth (sixth order overall).
  double lowpass_cutoff_hz = -1;
  // Samples whose time lies in [first, last] (s); all when unset.
  std::optional<std::pair<double, double>> time_range_s;
  // How to read a coordinates file that does not say inDegrees: old SIMM motion files are degrees.
  bool assume_degrees_when_unspecified = true;
  // Times to report (s), inside the data; the coordinates' own sample times when empty.
  std::vector<double> output_times_s;
};

// Coordinate trajectories at a table's sample times (or the requested output times): values, speeds
// and accelerations in internal units (rad, m). Unevenly spaced samples (times rounded in the file)
// are first resampled onto an even grid, as OpenSim does before filtering. Speeds and accelerations
// are the derivatives of an interpolating cubic spline (Forsythe-Malcolm-Moler) through the
// (filtered) samples.
struct CoordinateTrajectories {
  std::vector<double> time_s;
  Eigen::MatrixXd q, qd, qdd;  // samples x coordinates
  // The table's own rows, all of them (rad, m): neither resampled nor filtered. Fits to the recorded
  // poses (the feet's spheres and ground) use these, so that a table read back from its file gives
  // the fit the pipeline made from the same poses in memory.
  std::vector<double> recorded_time_s;
  Eigen::MatrixXd q_recorded;
  std::vector<std::string> warnings;
};
CoordinateTrajectories coordinate_trajectories(const Model& model, const Storage& coordinates,
                                               const InverseDynamicsOptions& options);
// Values, speeds and accelerations at time t, linear between the samples (held at the ends): what
// the simulations that track a trajectory (CMC, the Forward tool's correction, the reproduced gait)
// read between its dense samples.
void trajectories_at(const CoordinateTrajectories& k, double t_s, Eigen::VectorXd& q, Eigen::VectorXd& qd,
                     Eigen::VectorXd& qdd);

struct InverseDynamicsSummary {
  int frames = 0;
  double solve_seconds = 0;
  std::vector<std::string> warnings;
  double frames_per_second() const { return solve_seconds > 0 ? frames / solve_seconds : 0; }
  std::string BriefReport() const;
};

struct InverseDynamicsResult {
  std::vector<double> time_s;
  Eigen::MatrixXd generalized_forces;  // samples x coordinates: N m for angles, N for translations
  CoordinateTrajectories kinematics;   // what the forces were computed from
  InverseDynamicsSummary summary;
};

// One frame: generalized forces at (q, qd, qdd) and time t with the loads (nullptr: none). The
// stage runs this per sample; benchmarks time it alone.
struct InverseDynamicsFrameWorkspace {
  DynamicsWorkspace dynamics;
  KinematicsWorkspace<double> kinematics;  // body poses for loads expressed in body frames
  std::vector<Vector6d> external;
  std::vector<double> passive;  // the model's passive generalized forces
  explicit InverseDynamicsFrameWorkspace(const Model& m)
      : dynamics(m), kinematics(m), external(m.bodies.size()), passive(m.num_coordinates()) {}
};
void inverse_dynamics_frame(const Model& model, const double* q, const double* qd, const double* qdd, double t_s,
                            const AppliedLoads* loads, InverseDynamicsFrameWorkspace& ws, double* tau);

InverseDynamicsResult inverse_dynamics(const Model& model, const Storage& coordinates, const AppliedLoads* loads,
                                       const InverseDynamicsOptions& options = {}, Progress* progress = nullptr);

// OpenSim's output: columns <coordinate>_moment (angles) or <coordinate>_force (translations).
Storage inverse_dynamics_table(const Model& model, const InverseDynamicsResult& result);

}  // namespace cpgait
