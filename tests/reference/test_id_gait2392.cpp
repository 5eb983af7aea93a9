// Issue acceptance: inverse dynamics on OpenSim's gait2392 subject01 setup against OpenSim's output.
#include <gtest/gtest.h>

#include <cstdio>

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

// Per coordinate RMS difference over the common times; returns the worst ratio to the tolerance.
void compare(const Model& m, const InverseDynamicsResult& r, const Storage& ref, const char* who) {
  for (int c = 0; c < m.num_coordinates(); ++c) {
    const std::string label = m.coordinates[c].name + (m.coordinates[c].is_angle() ? "_moment" : "_force");
    const int col = ref.column(label);
    ASSERT_GE(col, 0) << label;
    double sum2 = 0, peak = 0;
    int n = 0;
    for (std::size_t i = 0; i < r.time_s.size(); ++i)
      for (int k = 0; k < ref.num_rows(); ++k)
        if (std::abs(ref.time()[k] - r.time_s[i]) < 1e-4) {
          sum2 += std::pow(r.generalized_forces(i, c) - ref.data(k, col), 2);
          peak = std::max(peak, std::abs(ref.data(k, col)));
          ++n;
        }
    ASSERT_GT(n, 50) << label;
    const double rms = std::sqrt(sum2 / n), tolerance = std::max(2.0, 0.05 * peak);
    EXPECT_LT(rms, tolerance) << label;
    std::printf("[ info ] vs %s: %-24s RMS %.3f (tolerance %.2f, peak %.1f, %d frames)\n", who, label.c_str(), rms,
                tolerance, peak, n);
  }
}

#define REQUIRE_ID_INPUTS()                                                                          \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_Setup_InverseDynamics.xml"));              \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim"));           \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_walk1_grf.mot"));                          \
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
  compare(m, r, read_storage(ref), "OpenSim published");
}

TEST(IdGait2392, MatchesOpenSim41RunOnTheSameFiles) {
  REQUIRE_ID_INPUTS();
  const std::string ref = refdata::shared_path("opensim41-here/ID/InverseDynamicsOutput.sto");
  REQUIRE_REFERENCE(ref);
  Model m;
  const InverseDynamicsResult r = run_setup(m);
  compare(m, r, read_storage(ref), "OpenSim 4.1");
}
