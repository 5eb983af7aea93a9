// Issue acceptance: inverse dynamics on OpenSim's gait2392 subject01 setup against OpenSim's output.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>

#include "cpgait/capture/id_setup.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

namespace {

InverseDynamicsResult run_setup(Model& model) {
  const IdSetup s = read_id_setup(refdata::gait2392("pipeline/subject01_Setup_InverseDynamics.xml"));
  model = read_osim(refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim")).model;
  const ExternalLoadsSpec spec = read_external_loads(refdata::gait2392("pipeline/subject01_walk1_grf.xml"));
  const AppliedLoads loads(model, spec, read_storage(refdata::gait2392("pipeline/subject01_walk1_grf.mot")));
  InverseDynamicsOptions o;
  o.lowpass_cutoff_hz = s.lowpass_cutoff_hz;
  o.time_range_s = s.time_range_s;
  return inverse_dynamics(model, read_storage(refdata::gait2392("pipeline/" + s.coordinates_file)), &loads, o);
}

// Per coordinate RMS differences (N m or N) measured when the regression bounds were set (issue 18).
const std::map<std::string, double> kMeasuredVsPublished = {
    {"pelvis_tilt_moment", 0.829}, {"pelvis_list_moment", 0.607}, {"pelvis_rotation_moment", 0.364}, {"pelvis_tx_force", 0.596},
    {"pelvis_ty_force", 0.675}, {"pelvis_tz_force", 0.41}, {"hip_flexion_r_moment", 0.586}, {"hip_adduction_r_moment", 0.325},
    {"hip_rotation_r_moment", 0.083}, {"knee_angle_r_moment", 0.059}, {"ankle_angle_r_moment", 0.025}, {"subtalar_angle_r_moment", 0.008},
    {"mtp_angle_r_moment", 0.003}, {"hip_flexion_l_moment", 0.607}, {"hip_adduction_l_moment", 0.426}, {"hip_rotation_l_moment", 0.149},
    {"knee_angle_l_moment", 0.046}, {"ankle_angle_l_moment", 0.023}, {"subtalar_angle_l_moment", 0.012}, {"mtp_angle_l_moment", 0.003},
    {"lumbar_extension_moment", 0.365}, {"lumbar_bending_moment", 0.609}, {"lumbar_rotation_moment", 0.269},
};
const std::map<std::string, double> kMeasuredVs41 = {
    {"pelvis_tilt_moment", 0.237}, {"pelvis_list_moment", 0.199}, {"pelvis_rotation_moment", 0.101}, {"pelvis_tx_force", 0.596},
    {"pelvis_ty_force", 0.675}, {"pelvis_tz_force", 0.41}, {"hip_flexion_r_moment", 0.168}, {"hip_adduction_r_moment", 0.138},
    {"hip_rotation_r_moment", 0.031}, {"knee_angle_r_moment", 0.069}, {"ankle_angle_r_moment", 0.007}, {"subtalar_angle_r_moment", 0.004},
    {"mtp_angle_r_moment", 0.001}, {"hip_flexion_l_moment", 0.159}, {"hip_adduction_l_moment", 0.192}, {"hip_rotation_l_moment", 0.04},
    {"knee_angle_l_moment", 0.051}, {"ankle_angle_l_moment", 0.006}, {"subtalar_angle_l_moment", 0.005}, {"mtp_angle_l_moment", 0.001},
    {"lumbar_extension_moment", 0.065}, {"lumbar_bending_moment", 0.087}, {"lumbar_rotation_moment", 0.02},
};

// Per coordinate RMS difference over the common times: within the target (2 N m or 5 % of the
// peak) and within the regression bound, 4x the figure measured (at least 0.02).
void compare(const Model& m, const InverseDynamicsResult& r, const Storage& ref, const char* who,
             const std::map<std::string, double>& measured) {
  const auto differences = refdata::column_differences(inverse_dynamics_table(m, r), ref, 1e-4);
  for (int c = 0; c < m.num_coordinates(); ++c) {
    const std::string label = m.coordinates[c].name + (m.coordinates[c].is_angle() ? "_moment" : "_force");
    ASSERT_EQ(differences.count(label), 1u) << label;
    const refdata::ColumnDifference& d = differences.at(label);
    ASSERT_GT(d.rows, 50) << label;
    const double tolerance = std::max(2.0, 0.05 * d.peak);
    ASSERT_EQ(measured.count(label), 1u) << label;
    const double regression = std::max(4 * measured.at(label), 0.02);
    EXPECT_TRUE(refdata::within_target_and_regression(d.rms, tolerance, regression)) << label;
    std::printf("[ info ] vs %s: %-24s RMS %.3f (target %.2f, regression bound %.3f, peak %.1f, %d frames)\n", who, label.c_str(), d.rms,
                tolerance, regression, d.peak, d.rows);
  }
}

#define REQUIRE_ID_INPUTS()                                                                          \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_Setup_InverseDynamics.xml"));              \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim"));           \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_walk1_grf.mot"));                          \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_walk1_grf.xml"));                          \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_walk1_ik.mot"))

}  // namespace

// Acceptance 1: every coordinate within 2 N m RMS (or 5 % of its peak) of OpenSim's published output.
TEST(IdGait2392, MatchesOpenSimsPublishedOutput) {
  REQUIRE_ID_INPUTS();
  const std::string ref = refdata::gait2392("pipeline/OutputReference/ResultsInverseDynamics/InverseDynamicsOutput.sto");
  REQUIRE_REFERENCE(ref);
  Model m;
  const InverseDynamicsResult r = run_setup(m);
  EXPECT_NEAR(r.time_s.front(), 0.5, 1e-6);  // the coordinates file starts at 0.5 s
  EXPECT_NEAR(r.time_s.back(), 1.6, 1e-6);
  compare(m, r, read_storage(ref), "OpenSim published", kMeasuredVsPublished);
}

TEST(IdGait2392, MatchesOpenSim41RunOnTheSameFiles) {
  REQUIRE_ID_INPUTS();
  const std::string ref = refdata::shared_path("opensim41-here/ID/InverseDynamicsOutput.sto");
  REQUIRE_REFERENCE(ref);
  Model m;
  const InverseDynamicsResult r = run_setup(m);
  compare(m, r, read_storage(ref), "OpenSim 4.1", kMeasuredVs41);
}
