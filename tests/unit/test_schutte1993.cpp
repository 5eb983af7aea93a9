// OpenSim's deprecated Schutte1993Muscle: its compliant-tendon dynamics (computeActuation), activation
// dynamics, static optimization's capacity for it, and the reader of its parameters.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "cpgait/capture/input_error.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/muscle_model.h"
#include "cpgait/muscles/schutte1993.h"
#include "test_support.h"

using namespace cpgait;

namespace {

// A pennate muscle with OpenSim's default Schutte curves (exponential passive force).
Muscle schutte_muscle() {
  Muscle m = refdata::pennate_muscle(1000, 0.1, 0.2, 0.2);
  m.name = "test";
  m.type = "Schutte1993Muscle";
  m.max_contraction_velocity = 10;
  m.min_control = 0;
  m.max_control = 1;
  schutte1993::Curves c = schutte1993::default_curves();
  c.exponential_passive = true;
  m.schutte = std::make_shared<const schutte1993::Curves>(c);
  return m;
}

// At OpenSim's isometric equilibrium the fibre is at rest and carries the tendon's force; a fibre
// longer than that slackens the tendon and shortens, a shorter one lengthens.
TEST(Schutte1993, FibreAtItsIsometricEquilibriumIsAtRestAndMovesBackToIt) {
  const Muscle m = schutte_muscle();
  for (double a : {0.05, 0.3, 1.0})
    for (double L : {0.27, 0.3, 0.32}) {
      const schutte1993::Isometric eq = schutte1993::isometric_equilibrium(m, a, L);
      ASSERT_GT(eq.tendon_force_N, 1.0) << a << " " << L;
      const CompliantTendonFiber at = muscles::compliant_tendon_fiber(m, a, L, eq.fiber_length_m);
      EXPECT_NEAR(at.force_N, eq.tendon_force_N, 1e-9) << a << " " << L;
      // The iteration stops within 0.01 N: the velocity that imbalance drives stays below 1e-4 m/s.
      EXPECT_LT(std::abs(at.fiber_velocity_m_s), 1e-4) << a << " " << L;
      EXPECT_LT(muscles::compliant_tendon_fiber(m, a, L, eq.fiber_length_m + 0.003).fiber_velocity_m_s, -1e-3) << a << " " << L;
      EXPECT_GT(muscles::compliant_tendon_fiber(m, a, L, eq.fiber_length_m - 0.003).fiber_velocity_m_s, 1e-3) << a << " " << L;
      // The equilibrium the dynamics start from is the same.
      EXPECT_EQ(muscles::compliant_equilibrium_fiber_length(m, a, L, 0.0), eq.fiber_length_m);
    }
}

// Held at its equilibrium excitation and length, CMC's predictor keeps the muscle where it is.
TEST(Schutte1993, PredictorHoldsAnIsometricMuscleInEquilibrium) {
  const Muscle m = schutte_muscle();
  const double a = 0.4, L = 0.3;
  const schutte1993::Isometric eq = schutte1993::isometric_equilibrium(m, a, L);
  const CompliantMuscleState after = muscles::compliant_muscle_after(m, a, eq.fiber_length_m, L, L, a, 0.05);
  EXPECT_NEAR(after.activation, a, 1e-12);
  EXPECT_NEAR(after.fiber_length_m, eq.fiber_length_m, 1e-6);
  EXPECT_NEAR(after.force_N, eq.tendon_force_N, 0.5);
  // Excited fully, it pulls harder by the window's end.
  EXPECT_GT(muscles::compliant_muscle_after(m, a, eq.fiber_length_m, L, L, 1.0, 0.05).force_N, eq.tendon_force_N + 50);
}

// computeActuation's activation rate, with its own constants, through the dispatch every caller uses.
TEST(Schutte1993, ActivationRateIsSchuttesWithTheModelsConstants) {
  Muscle m = schutte_muscle();
  EXPECT_NEAR(thelen_activation_rate(m, 0.8, 0.3), 0.5 * (7.667 * 0.8 + 1.459854) / 0.1, 1e-9);
  EXPECT_NEAR(thelen_activation_rate(m, 0.1, 0.3), -0.2 * 1.459854 / 0.1, 1e-9);
  schutte1993::Curves c = *m.schutte;
  c.time_scale_s = 0.2;
  c.activation1 = 5;
  m.schutte = std::make_shared<const schutte1993::Curves>(c);
  EXPECT_NEAR(thelen_activation_rate(m, 0.8, 0.3), 0.5 * (5 * 0.8 + 1.459854) / 0.2, 1e-9);
}

// Static optimization's capacity (calcInextensibleTendonActiveFiberForce of OpenSim's deprecated
// muscles): the isometric force at full activation scaled by the generic force-velocity factor, which
// is 1.8 - 1.8 / (1 + e^((0.04 - v) / 0.18)) at normalised shortening velocity v.
TEST(Schutte1993, StaticOptimizationCapacityIsTheIsometricForceTimesTheForceVelocityFactor) {
  const Muscle m = schutte_muscle();
  const double L = 0.3, F_iso = schutte1993::isometric_equilibrium(m, 1.0, L).tendon_force_N;
  const double at_rest = schutte1993::inextensible_tendon_active_force(m, 1.0, L, 0.0);
  EXPECT_NEAR(at_rest, F_iso * (1.8 - 1.8 / (1 + std::exp(0.04 / 0.18))), 1e-9);
  // Shortening at a fifth of the maximum speed along the path (0.2 m/s here).
  const double v = 0.2 * std::cos(0.2);
  EXPECT_NEAR(schutte1993::inextensible_tendon_active_force(m, 1.0, L, -0.2), F_iso * (1.8 - 1.8 / (1 + std::exp((0.04 - v) / 0.18))),
              1e-9);
  EXPECT_LT(schutte1993::inextensible_tendon_active_force(m, 1.0, L, -0.2), at_rest);
  EXPECT_GT(schutte1993::inextensible_tendon_active_force(m, 1.0, L, 0.2), at_rest);
}

// Rigid tendons (the gait's default): the model's own curves, not Thelen's.
TEST(Schutte1993, RigidTendonForcesUseItsOwnCurves) {
  const Muscle m = schutte_muscle();
  const double lm = m.optimal_fiber_length_m, along = lm * std::cos(0.2), L = m.tendon_slack_length_m + along;
  EXPECT_NEAR(muscles::rigid_tendon_fiber_length(m, L), lm, 1e-12);
  const RigidTendonForces f = muscles::rigid_tendon_forces(m, 0.5, L, 0.0);
  const double fv0 = 1.8 - 1.8 / (1 + std::exp(0.04 / 0.18));
  EXPECT_NEAR(f.active_N, 1000 * 0.5 * m.schutte->active_force_length.value(1.0) * fv0 * std::cos(0.2), 1e-9);
  EXPECT_NEAR(f.passive_N, 1000 * std::exp(0.0) / std::exp(4.0) * std::cos(0.2), 1e-9);
}

// BothLegs' muscles are Schutte1993Muscles: their time scale and activation constants come from the
// document, and a time scale that is not positive is refused naming the file, line and field.
TEST(Schutte1993, ReaderTakesItsConstantsAndRefusesABadTimeScale) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/Analyze/BothLegs.osim");
  REQUIRE_REFERENCE(path);
  std::stringstream text;
  text << std::ifstream(path).rdbuf();
  std::string doc = text.str();
  auto replace_first = [](std::string s, const std::string& from, const std::string& to) {
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  const std::string dir = refdata::temp_dir("schutte_reader");
  const std::string changed = dir + "/BothLegs.osim";
  std::ofstream(changed) << replace_first(replace_first(doc, "<time_scale>0.1</time_scale>", "<time_scale>0.25</time_scale>"),
                                          "<activation1>7.667</activation1>", "<activation1>6.5</activation1>");
  const OsimReadResult r = read_osim(changed);
  ASSERT_FALSE(r.model.muscles.empty());
  const Muscle& first = r.model.muscles[0];
  ASSERT_TRUE(first.schutte);
  EXPECT_EQ(first.schutte->time_scale_s, 0.25);
  EXPECT_EQ(first.schutte->activation1, 6.5);
  EXPECT_EQ(first.schutte->activation2, 1.459854);
  ASSERT_TRUE(r.model.muscles[1].schutte);
  EXPECT_EQ(r.model.muscles[1].schutte->time_scale_s, 0.1);
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("Thelen"), std::string::npos) << w;

  const std::string bad = dir + "/bad.osim";
  std::ofstream(bad) << replace_first(doc, "<time_scale>0.1</time_scale>", "<time_scale>0</time_scale>");
  try {
    read_osim(bad);
    ADD_FAILURE() << "a zero time_scale was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "time_scale");
    const std::string before = doc.substr(0, doc.find("<time_scale>"));
    EXPECT_EQ(e.line(), 1 + std::count(before.begin(), before.end(), '\n'));  // the element's own line
    EXPECT_NE(std::string(e.what()).find("GMED1"), std::string::npos) << e.what();
  }
}

}  // namespace
