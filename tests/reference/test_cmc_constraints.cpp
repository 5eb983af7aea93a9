// CMC on a model with constrained coordinates, as OpenSim's own test runs it (testCMCLeg6Dof9Musc's
// swing: leg6dof9musc, the patella coupled to the knee, the pelvis's three coordinates locked by the
// test before it runs). The constraints hold exactly and the tracked joints follow OpenSim's run;
// OpenSim's test also holds speeds and activations to 0.05 RMS, which cpgait's CMC does not meet yet
// (measured 0.15-0.22 rad/s and up to 0.12; issue 23).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cpgait/capture/storage.h"
#include "test_support.h"

namespace cpgait {
namespace {
namespace fs = std::filesystem;

TEST(CmcConstraints, Leg6Dof9MuscSwingKeepsLockedAndCoupledCoordinates) {
  const std::string in = refdata::shared_path("opensim/opensim-core-tests/CMC/");
  const std::vector<std::string> files = {"leg6dof9musc_setup_Swing.xml", "leg69_IK_swing.mot", "leg69_CMC_Swing_Tracking_Tasks.xml",
                                          "leg69_muscles_control_limits.xml"};
  for (const auto& f : files) REQUIRE_REFERENCE(in + f);
  REQUIRE_REFERENCE(in + "leg6dof9musc.osim");
  REQUIRE_REFERENCE(in + "Leg6Dof9MuscSwing_std_leg6dof9musc_states.sto");
  const std::string dir = refdata::temp_dir("cmc_leg69_swing");
  for (const auto& f : files) fs::copy_file(in + f, dir + "/" + f);
  // The first three coordinates locked, as the test does with setDefaultLocked(true).
  std::ifstream src(in + "leg6dof9musc.osim");
  std::stringstream text;
  text << src.rdbuf();
  std::string model = text.str();
  std::size_t at = 0;
  for (int i = 0; i < 3; ++i) {
    at = model.find("<locked>false</locked>", at);
    ASSERT_NE(at, std::string::npos);
    model.replace(at, 22, "<locked>true</locked>");
  }
  std::ofstream(dir + "/leg6dof9musc.osim") << model;
  const auto run = refdata::run_cpgait("run-tool " + dir + "/leg6dof9musc_setup_Swing.xml --results " + dir + "/out");
  ASSERT_EQ(run.status, 0) << run.output;

  const Storage ours = read_storage(dir + "/out/leg6dof9musc_states.sto");
  const Storage theirs = read_storage(in + "Leg6Dof9MuscSwing_std_leg6dof9musc_states.sto");
  const int tilt = refdata::required_column(ours, "pelvis_tilt"), ty = refdata::required_column(ours, "pelvis_ty");
  const int knee = refdata::required_column(ours, "knee_angle_r"), pat = refdata::required_column(ours, "knee_angle_pat_r");
  double locked_drift = 0, coupling = 0;
  for (int k = 0; k < ours.num_rows(); ++k) {
    locked_drift = std::max({locked_drift, std::abs(ours.data(k, tilt) - 0.0200194), std::abs(ours.data(k, ty) - 1.06004667)});
    coupling = std::max(coupling, std::abs(ours.data(k, pat) - ours.data(k, knee)));  // its function is q_pat = q_knee
  }
  std::printf("locked pelvis: largest move %.1e; patella off the knee by at most %.1e rad\n", locked_drift, coupling);
  EXPECT_LT(locked_drift, 1e-12);  // held at the model's default values, where OpenSim holds them
  EXPECT_LT(coupling, 1e-9);
  // The tracked joints against OpenSim's run, up to 40 ms before the end (past it the desired
  // kinematics run out and both solves chase the data's end).
  const Eigen::VectorXd t = ours.time();
  const double t_last = t[t.size() - 1] - 0.04;
  int compared = 0;
  for (const char* name : {"hip_flexion_r", "knee_angle_r", "knee_angle_pat_r", "ankle_angle_r"}) {
    const int o = refdata::required_column(ours, name);
    const int r = refdata::required_column(theirs, std::string("/jointset/") +
                                                       (std::string(name) == "hip_flexion_r" ? "hip_r"
                                                        : std::string(name) == "ankle_angle_r" ? "ankle_r"
                                                        : std::string(name) == "knee_angle_r" ? "knee_r" : "tib_pat_r") +
                                                       "/" + name + "/value");
    double sum2 = 0;
    int rows = 0;
    for (int k = 0; k < theirs.num_rows(); ++k) {
      const double tk = theirs.data(k, 0);
      if (tk < t[0] || tk > t_last) continue;
      const Eigen::Index j = std::upper_bound(t.data(), t.data() + t.size(), tk) - t.data();
      const double w = (tk - t[j - 1]) / (t[j] - t[j - 1]);
      sum2 += std::pow((1 - w) * ours.data(j - 1, o) + w * ours.data(j, o) - theirs.data(k, r), 2);
      ++rows;
    }
    const double rms = std::sqrt(sum2 / rows);
    std::printf("%-17s RMS %.4f rad against OpenSim over %d rows\n", name, rms, rows);
    EXPECT_GT(rows, 100);
    EXPECT_LT(rms, 0.05) << name;  // measured at most 0.030 (hip)
    ++compared;
  }
  EXPECT_EQ(compared, 4);
}

}  // namespace
}  // namespace cpgait
