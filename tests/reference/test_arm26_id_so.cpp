// arm26 (wrap cylinders and ellipsoids) through run-tool on OpenSim's own test setups, against the
// standards OpenSim's tests hold it to (opensim-core-tests/Analyze: testID, testStaticOptimization).
#include <gtest/gtest.h>

#include <filesystem>

#include "cpgait/capture/storage.h"
#include "test_support.h"

namespace cpgait {
namespace {
namespace fs = std::filesystem;

std::string analyze(const std::string& f) { return refdata::shared_path("opensim/opensim-core-tests/Analyze/" + f); }

// The setup beside its model and motion in a fresh folder, run; the results folder.
std::string run_arm26_setup(const std::string& setup, const std::string& name) {
  const std::string dir = refdata::temp_dir(name);
  for (const auto& f : {setup, std::string("arm26.osim"), std::string("arm26_InverseKinematics.mot")})
    fs::copy_file(analyze(f), dir + "/" + f);
  const auto run = refdata::run_cpgait("run-tool " + dir + "/" + setup + " --results " + dir + "/out");
  EXPECT_EQ(run.status, 0) << run.output;
  return dir + "/out/";
}

TEST(Arm26Reference, InverseDynamicsMatchesOpenSimsStandard) {
  for (const auto& f : {"arm26.osim", "arm26_InverseKinematics.mot", "arm26_Setup_InverseDynamics.xml", "std_arm26_InverseDynamics.sto"})
    REQUIRE_REFERENCE(analyze(f));
  const std::string out = run_arm26_setup("arm26_Setup_InverseDynamics.xml", "arm26_id");
  const auto diff = refdata::column_differences(read_storage(out + "arm26_InverseDynamics.sto"),
                                                read_storage(analyze("std_arm26_InverseDynamics.sto")), 1e-6);
  ASSERT_EQ(diff.size(), 2u);
  for (const auto& [column, d] : diff) {
    std::printf("%s: RMS %.2e N m over %d frames (peak %.2f)\n", column.c_str(), d.rms, d.rows, d.peak);
    EXPECT_GE(d.rows, 120) << column;
    // Measured 6.4e-4 and 3.7e-4 N m; the target 0.1 N m (OpenSim's own test allows 0.01).
    EXPECT_TRUE(refdata::within_target_and_regression(d.rms, 0.1, 2e-3)) << column;
  }
}

TEST(Arm26Reference, StaticOptimizationMatchesOpenSimsThelenStandard) {
  const std::string act_ref = analyze("std_Thelen2003Muscle_arm26_StaticOptimization_activation.sto");
  const std::string force_ref = analyze("std_Thelen2003Muscle_arm26_StaticOptimization_force.sto");
  for (const auto& f : {analyze("arm26.osim"), analyze("arm26_Setup_StaticOptimization.xml"), act_ref, force_ref}) REQUIRE_REFERENCE(f);
  const std::string out = run_arm26_setup("arm26_Setup_StaticOptimization.xml", "arm26_so");
  const Storage act = read_storage(out + "arm26_StaticOptimization_activation.sto");
  const Storage force = read_storage(out + "arm26_StaticOptimization_force.sto");
  const Storage act_std = read_storage(act_ref), force_std = read_storage(force_ref);
  // Rows match by index: OpenSim's first time is -2e-7 s where ours is 0.
  ASSERT_EQ(act.num_rows(), act_std.num_rows());
  const auto act_diff = refdata::column_differences(act, act_std, 1e-6);
  const auto force_diff = refdata::column_differences(force, force_std, 1e-6);
  ASSERT_EQ(act_diff.size(), 6u);
  for (const auto& [muscle, d] : act_diff) {
    const auto& f = force_diff.at(muscle);
    std::printf("%-8s activation RMS %.4f (peak %.3f), force RMS %.3f N (peak %.1f N)\n", muscle.c_str(), d.rms, d.peak, f.rms,
                f.peak);
    EXPECT_GE(d.rows, 119) << muscle;
    // Measured at most 0.0018 (BRA); the target 0.01 (OpenSim's own test allows 0.025).
    EXPECT_TRUE(refdata::within_target_and_regression(d.rms, 0.01, 0.005)) << muscle;
    // Forces: the target, 1 % of the muscle's peak, holds for the three that carry the load
    // (measured 0.12-0.74 %). The three below 15 N differ by up to 1.6 N RMS (BRA, peak 4 N): at
    // those activations OpenSim's optimizer stops short of the optimum (next test); OpenSim's own
    // test allows 4 N RMS.
    if (f.peak > 50) EXPECT_LT(f.rms, 0.01 * f.peak) << muscle;
    else EXPECT_LT(f.rms, 2.0) << muscle;
  }
  // The sum of squared activations, which both minimise under the same moment balance: ours is as
  // low or lower (within 1e-4) at every frame but one, 1.5e-3 higher there (measured).
  int ours_higher = 0;
  double worst = 0;
  for (int k = 0; k < act.num_rows(); ++k) {
    double ours = 0, theirs = 0;
    for (int c = 1; c < act_std.num_columns(); ++c) {
      theirs += std::pow(act_std.data(k, c), 2);
      ours += std::pow(act.data(k, refdata::required_column(act, act_std.labels[c])), 2);
    }
    worst = std::max(worst, ours / theirs - 1);
    ours_higher += ours > theirs * (1 + 1e-4) ? 1 : 0;
  }
  std::printf("sum of squared activations: ours above OpenSim's (by > 1e-4) at %d of %d frames, at most %.1e\n", ours_higher,
              act.num_rows(), worst);
  EXPECT_LE(ours_higher, 2);
  EXPECT_LT(worst, 5e-3);
}

}  // namespace
}  // namespace cpgait
