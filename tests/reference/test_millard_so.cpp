// Static optimization with Millard2012EquilibriumMuscle through run-tool on OpenSim's own test setups
// (opensim-core-tests/Analyze, testStaticOptimization): the gait model with an ankle
// CoordinateLimitForce, whose standard OpenSim 4 wrote in 2020, and arm26 made a Millard model as
// OpenSim's test makes it (every Thelen2003Muscle element read as a Millard2012EquilibriumMuscle).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <sstream>

#include "cpgait/capture/storage.h"
#include "test_support.h"

namespace cpgait {
namespace {
namespace fs = std::filesystem;

std::string analyze(const std::string& f) { return refdata::shared_path("opensim/opensim-core-tests/Analyze/" + f); }

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::vector<std::string> kSpringFiles = {"staticoptimization_spring_Setup.xml", "gait10dof_Actuators_weak.xml",
                                               "externalForces.xml", "subject01_walk1_grf.mot",
                                               "walk_subject01_Kinematics_q.sto"};

// The spring setup in a fresh folder with the model as given (edited by `edit`); the activations.
Storage run_spring_setup(const std::string& name, const std::function<std::string(std::string)>& edit) {
  const std::string dir = refdata::temp_dir(name);
  for (const auto& f : kSpringFiles) fs::copy_file(analyze(f), dir + "/" + f);
  std::ofstream(dir + "/subject01_adjusted_spring.osim") << edit(read_text(analyze("subject01_adjusted_spring.osim")));
  const auto run = refdata::run_cpgait("run-tool " + dir + "/staticoptimization_spring_Setup.xml --results " + dir + "/out");
  EXPECT_EQ(run.status, 0) << run.output;
  return read_storage(dir + "/out/walk_subject01_ankle_spring_StaticOptimization_activation.sto");
}

TEST(MillardStaticOptimization, GaitModelWithAnkleSpringMatchesOpenSim4) {
  const std::string std_act = analyze("std_walk_subject01_ankle_spring_StaticOptimization_activation.sto");
  for (const auto& f : kSpringFiles) REQUIRE_REFERENCE(analyze(f));
  REQUIRE_REFERENCE(analyze("subject01_adjusted_spring.osim"));
  REQUIRE_REFERENCE(std_act);
  const Storage reference = read_storage(std_act);
  const Storage act = run_spring_setup("so_spring", [](std::string s) { return s; });
  // OpenSim records the range's first and last rows and every row whose index is a multiple of 10:
  // the file's uneven rows put those at 0.503, 0.513, ... s; every one of the 84 times matches.
  const auto diff = refdata::column_differences(act, reference, 1e-6);
  ASSERT_EQ(diff.size(), 28u);
  int muscles_checked = 0;
  for (const auto& [name, d] : diff) {
    EXPECT_EQ(d.rows, 84) << name;
    if (name.find("reserve") != std::string::npos || name == "FX" || name == "FY" || name == "MZ") continue;
    std::printf("%-13s activation RMS %.4f (peak %.3f)\n", name.c_str(), d.rms, d.peak);
    // The target: 0.02 RMS for muscles that peak above 0.05; measured at most 0.0024
    // (iliopsoas_l). OpenSim's own test allows 0.025.
    if (d.peak > 0.05) {
      EXPECT_TRUE(refdata::within_target_and_regression(d.rms, 0.02, 0.005)) << name;
      ++muscles_checked;
    } else {
      EXPECT_LT(d.rms, 0.002) << name;
    }
  }
  EXPECT_EQ(muscles_checked, 16);

  // The ankle's CoordinateLimitForce carries much of the ankle moment: without it the right leg's
  // activations are far from OpenSim's (tib_ant_r measured 0.51 RMS), so the test above exercises it.
  const Storage no_spring = run_spring_setup("so_no_spring", [](std::string s) {
    return std::regex_replace(s, std::regex("<CoordinateLimitForce name=\"AnkleLimitSpringDamper\">"),
                              "<CoordinateLimitForce name=\"AnkleLimitSpringDamper\"><isDisabled>true</isDisabled>");
  });
  EXPECT_GT(refdata::column_differences(no_spring, reference, 1e-6).at("tib_ant_r").rms, 0.1);
}

// OpenSim's standard for this variant dates from August 2012 (opensim-core e1936439c), before
// OpenSim 3.0 settled Millard's default curves (active force-length transition 0.6259 -> 0.73, widest
// length 1.5959 -> 1.8123, eccentric force 1.8 -> 1.4, force-velocity rebuilt from four corners):
// OpenSim 4 itself no longer reproduces it and its test allows 0.04 RMS in activation and 5 N in force.
// cpgait computes OpenSim 4's curves, so this holds it to OpenSim's own tolerance; the exact check of
// the Millard curves is the spring model above, whose standard OpenSim 4 wrote.
TEST(MillardStaticOptimization, Arm26MillardVariantWithinOpenSimsTolerance) {
  const std::string std_act = analyze("std_Millard2012EquilibriumMuscle_arm26_StaticOptimization_activation.sto");
  const std::string std_force = analyze("std_Millard2012EquilibriumMuscle_arm26_StaticOptimization_force.sto");
  for (const auto& f : {analyze("arm26.osim"), analyze("arm26_InverseKinematics.mot"), analyze("arm26_Setup_StaticOptimization.xml"),
                        std_act, std_force})
    REQUIRE_REFERENCE(f);
  const std::string dir = refdata::temp_dir("arm26_millard_so");
  for (const auto& f : {"arm26_InverseKinematics.mot", "arm26_Setup_StaticOptimization.xml"}) fs::copy_file(analyze(f), dir + "/" + f);
  std::ofstream(dir + "/arm26.osim") << std::regex_replace(read_text(analyze("arm26.osim")), std::regex("Thelen2003Muscle"),
                                                           "Millard2012EquilibriumMuscle");
  const auto run = refdata::run_cpgait("run-tool " + dir + "/arm26_Setup_StaticOptimization.xml --results " + dir + "/out");
  ASSERT_EQ(run.status, 0) << run.output;
  const auto act = refdata::column_differences(read_storage(dir + "/out/arm26_StaticOptimization_activation.sto"),
                                               read_storage(std_act), 1e-6);
  const auto force = refdata::column_differences(read_storage(dir + "/out/arm26_StaticOptimization_force.sto"),
                                                 read_storage(std_force), 1e-6);
  ASSERT_EQ(act.size(), 6u);
  for (const auto& [muscle, d] : act) {
    std::printf("%-8s activation RMS %.4f (peak %.3f), force RMS %.2f N\n", muscle.c_str(), d.rms, d.peak, force.at(muscle).rms);
    EXPECT_EQ(d.rows, 61) << muscle;
    // Measured at most 0.025 (BIClong) and 4.99 N (BICshort).
    EXPECT_LT(d.rms, 0.04) << muscle;
    EXPECT_LT(force.at(muscle).rms, 5.0) << muscle;
  }
}

}  // namespace
}  // namespace cpgait
