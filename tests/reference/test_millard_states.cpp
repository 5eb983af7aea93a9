// Millard2012EquilibriumMuscle's fibre dynamics against OpenSim's own integration of them: OpenSim's
// CMC standard for gait10dof18musc (opensim-core-tests/CMC, written by OpenSim 4 in 2023) records
// each muscle's activation and fibre length at the integrator's steps, microseconds apart at first.
// The fibre length's rate between steps is OpenSim's fibre velocity; ours at the recorded state
// (path length from the recorded pose, activation and fibre length as recorded) must agree. That
// exercises the curves, the pennation, the tendon and the damped velocity solve together.
#include <gtest/gtest.h>

#include "cpgait/capture/storage.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_model.h"
#include "cpgait/muscles/muscle_path.h"
#include "test_support.h"

namespace cpgait {
namespace {

std::string cmc(const std::string& f) { return refdata::shared_path("opensim/opensim-core-tests/CMC/" + f); }

TEST(MillardReference, FibreVelocityMatchesOpenSimsCmcStates) {
  const std::string model_path = cmc("gait10dof18musc_subject01.osim"), states_path = cmc("gait10dof18musc_std_walk_subject_states_unix.sto");
  REQUIRE_REFERENCE(model_path);
  REQUIRE_REFERENCE(states_path);
  const Model m = read_osim(model_path).model;
  const Storage s = read_storage(states_path);
  const int nq = m.num_coordinates(), nm = static_cast<int>(m.muscles.size());
  ASSERT_EQ(nm, 18);
  std::vector<int> q_col(nq), u_col(nq), a_col(nm), l_col(nm);
  for (int c = 0; c < nq; ++c) {
    const Coordinate& co = m.coordinates[c];
    const std::string joint = m.joints[co.joint].name;
    q_col[c] = refdata::required_column(s, "/jointset/" + joint + "/" + co.name + "/value");
    u_col[c] = refdata::required_column(s, "/jointset/" + joint + "/" + co.name + "/speed");
  }
  for (int k = 0; k < nm; ++k) {
    a_col[k] = refdata::required_column(s, "/forceset/" + m.muscles[k].name + "/activation");
    l_col[k] = refdata::required_column(s, "/forceset/" + m.muscles[k].name + "/fiber_length");
  }
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  MusclePathGeometry g(m);
  Eigen::VectorXd q(nq), u(nq);
  // Our fibre velocities at every recorded state.
  Eigen::MatrixXd ours(s.num_rows(), nm);
  for (int i = 0; i < s.num_rows(); ++i) {
    for (int c = 0; c < nq; ++c) q[c] = s.data(i, q_col[c]), u[c] = s.data(i, u_col[c]);
    forward_kinematics(m, q.data(), ws);
    motion_subspace(m, q.data(), ws, S);
    muscle_path_geometry(m, q.data(), u.data(), ws, S, g);
    for (int k = 0; k < nm; ++k)
      ours(i, k) = muscles::compliant_tendon_fiber(m.muscles[k], s.data(i, a_col[k]), g.length_m[k], s.data(i, l_col[k])).fiber_velocity_m_s;
  }
  // Per muscle: OpenSim's change of fibre length over a step against the trapezoid of our velocities
  // at its ends (second order for any spacing), normalised by optimal length x max velocity.
  std::vector<double> sum_sq(nm, 0.0), peak(nm, 0.0);
  int pairs = 0;
  for (int i = 0; i + 1 < s.num_rows(); ++i) {
    const double dt = s.data(i + 1, 0) - s.data(i, 0);
    if (dt <= 0 || dt > 2e-3) continue;  // the recorded steps reach 2 ms
    for (int k = 0; k < nm; ++k) {
      const Muscle& mu = m.muscles[k];
      const double theirs = (s.data(i + 1, l_col[k]) - s.data(i, l_col[k])) / dt;
      const double scale = mu.optimal_fiber_length_m * mu.max_contraction_velocity;
      sum_sq[k] += std::pow((0.5 * (ours(i, k) + ours(i + 1, k)) - theirs) / scale, 2);
      peak[k] = std::max(peak[k], std::abs(theirs / scale));
    }
    ++pairs;
  }
  ASSERT_GT(pairs, 350);
  double worst = 0;
  for (int k = 0; k < nm; ++k) {
    const double rms = std::sqrt(sum_sq[k] / pairs);
    std::printf("%-13s normalised fibre velocity RMS difference %.2e (OpenSim's peak %.3f)\n", m.muscles[k].name.c_str(), rms, peak[k]);
    worst = std::max(worst, rms);
  }
  std::printf("%d steps; worst %.2e\n", pairs, worst);
  // Measured at most 9.1e-4 (gastroc_l; most muscles 1-2e-4, the size of the file's 8-digit rounding
  // over the shortest steps).
  EXPECT_LT(worst, 2e-3);
}

}  // namespace
}  // namespace cpgait
