// Millard2012EquilibriumMuscle's curves as OpenSim's SmoothSegmentedFunctionFactory builds them, the
// reader of their properties, and OpenSim's CoordinateLimitForce.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/millard2012.h"
#include "test_support.h"

using namespace cpgait;

namespace {

// Central difference of a curve's value, to check its analytic slope.
double numeric_slope(const SmoothSegmentedFunction& f, double x) {
  const double h = 1e-6;
  return (f.value(x + h) - f.value(x - h)) / (2 * h);
}

// Each curve passes through the points and slopes its construction names, and its slope is the
// derivative of its value everywhere, across the joins between its Bezier segments included.
TEST(Millard2012, CurvesHaveTheirDefiningValuesAndSlopes) {
  millard2012::Parameters p;  // OpenSim's defaults
  const millard2012::Curves c = millard2012::make_curves(p);
  const auto& fal = c.active_force_length;
  // Damped (OpenSim's default 0.1): the minimum value and the end slopes of fv are zero.
  EXPECT_TRUE(c.use_fiber_damping);
  EXPECT_NEAR(fal.value(1.0), 1.0, 1e-12);
  EXPECT_NEAR(fal.derivative(1.0), 0.0, 1e-10);
  EXPECT_NEAR(fal.value(0.4441), 0.0, 1e-12);
  EXPECT_NEAR(fal.value(1.8123), 0.0, 1e-12);
  EXPECT_EQ(fal.value(0.3), 0.0);
  EXPECT_EQ(fal.value(2.0), 0.0);
  const auto& fv = c.force_velocity;
  EXPECT_NEAR(fv.value(0.0), 1.0, 1e-12);
  EXPECT_NEAR(fv.derivative(0.0), 5.0, 1e-9);  // isometric_slope
  EXPECT_NEAR(fv.value(-1.0), 0.0, 1e-12);
  EXPECT_NEAR(fv.value(1.0), 1.4, 1e-12);
  EXPECT_EQ(fv.value(-1.5), 0.0);
  EXPECT_EQ(fv.value(1.5), 1.4);
  const auto& fpe = c.fiber_force_length;
  EXPECT_EQ(fpe.value(0.9), 0.0);
  EXPECT_NEAR(fpe.value(1.0), 0.0, 1e-12);
  EXPECT_NEAR(fpe.value(1.7), 1.0, 1e-12);                // strain_at_one_norm_force 0.7
  EXPECT_NEAR(fpe.derivative(1.7), 2.0 / 0.7, 1e-9);      // the fitted curve's stiffness
  EXPECT_NEAR(fpe.value(1.8), 1.0 + 0.1 * 2.0 / 0.7, 1e-12);  // linear beyond
  const auto& fse = c.tendon_force_length;
  EXPECT_NEAR(fse.value(1.0), 0.0, 1e-12);
  EXPECT_NEAR(fse.value(1.049), 1.0, 1e-12);  // strain_at_one_norm_force 0.049, on the linear part
  EXPECT_NEAR(fse.derivative(1.049), 1.375 / 0.049, 1e-9);
  EXPECT_NEAR(fse.value(fse.x_end()), 2.0 / 3.0, 1e-12);  // the toe ends at 2/3 of max isometric force

  for (const SmoothSegmentedFunction* f : {&fal, &fv, &fpe, &fse}) {
    double worst = 0;
    for (int i = 1; i < 2000; ++i) {
      const double x = f->x_begin() + (f->x_end() - f->x_begin()) * i / 2000.0;
      worst = std::max(worst, std::abs(f->derivative(x) - numeric_slope(*f, x)));
    }
    EXPECT_LT(worst, 1e-5);
  }
  // fv, fpe and fse rise everywhere (the equilibrium solves rely on it).
  for (const SmoothSegmentedFunction* f : {&fv, &fpe, &fse})
    for (int i = 1; i < 2000; ++i) {
      const double x0 = f->x_begin() + (f->x_end() - f->x_begin()) * (i - 1) / 2000.0;
      const double x1 = f->x_begin() + (f->x_end() - f->x_begin()) * i / 2000.0;
      ASSERT_GE(f->value(x1), f->value(x0)) << x1;
    }
}

// An undamped elastic tendon keeps OpenSim's singularity guards: the active-force-length curve never
// drops below 0.1 and the force-velocity curve keeps a slope of 0.1 at its ends.
TEST(Millard2012, UndampedElasticTendonKeepsTheCurvesAwayFromZero) {
  millard2012::Parameters p;
  p.fiber_damping = 0.0;
  const millard2012::Curves c = millard2012::make_curves(p);
  EXPECT_FALSE(c.use_fiber_damping);
  EXPECT_NEAR(c.active_force_length.value(0.3), 0.1, 1e-12);
  EXPECT_NEAR(c.force_velocity.derivative(-1.2), 0.1, 1e-12);
  EXPECT_NEAR(c.force_velocity.derivative(1.2), 0.1, 1e-12);
  p.minimum_activation = 0.0;
  EXPECT_THROW(millard2012::make_curves(p), std::invalid_argument);
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// OpenSim's tug-of-war model gives every curve property, some of them empty (OpenSim's "use the
// fitted curve"): the curves follow them.
TEST(Millard2012, ReaderTakesTheDocumentsCurveProperties) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/Analyze/Tug_of_War_Millard_Iso.osim");
  REQUIRE_REFERENCE(path);
  const Model m = read_osim(path).model;
  ASSERT_FALSE(m.muscles.empty());
  const Muscle& mu = m.muscles[0];
  ASSERT_TRUE(mu.millard);
  EXPECT_DOUBLE_EQ(mu.millard->parameters.active_force_length.transition_norm_fiber_length, 0.6259);
  EXPECT_DOUBLE_EQ(mu.millard->parameters.fiber_force_length.strain_at_one_norm_force, 0.6);
  EXPECT_FALSE(mu.millard->parameters.fiber_force_length.curviness.has_value());
  EXPECT_NEAR(mu.millard->fiber_force_length.value(1.6), 1.0, 1e-12);
  EXPECT_NEAR(mu.millard->fiber_force_length.derivative(1.6), 2.0 / 0.6, 1e-9);
  EXPECT_DOUBLE_EQ(mu.min_control, 0.0);  // the document's, not minimum_activation's 0.01

  // A property that breaks OpenSim's conditions is refused naming the muscle's line.
  const std::string bad = std::regex_replace(read_text(path), std::regex("<shallow_ascending_slope>0.8616"),
                                             "<shallow_ascending_slope>3");
  try {
    parse_osim(bad, "tug.osim");
    FAIL() << "accepted a shallow_ascending_slope above OpenSim's bound";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("shallow_ascending_slope"), std::string::npos) << e.what();
    EXPECT_GT(e.line(), 1) << e.what();
  }
}

// CoordinateLimitForce: nothing inside the range, a spring switched on by a quintic step over the
// transition, and damping only while a spring is on; degrees converted as OpenSim converts them.
TEST(CoordinateLimitForce, SpringAndDampingPastEachLimit) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/Analyze/subject01_adjusted_spring.osim");
  REQUIRE_REFERENCE(path);
  const OsimReadResult r = read_osim(path);
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("CoordinateLimitForce"), std::string::npos) << w;
  ASSERT_EQ(r.model.coordinate_limit_forces.size(), 1u);
  const CoordinateLimitForce& f = r.model.coordinate_limit_forces[0];
  EXPECT_EQ(r.model.coordinates[f.coordinate].name, "ankle_angle_r");
  const double deg = M_PI / 180;
  EXPECT_NEAR(f.upper_limit, 5 * deg, 1e-15);
  EXPECT_NEAR(f.upper_stiffness, 30 / deg, 1e-9);  // 30 N m per degree
  EXPECT_NEAR(f.damping, 0.01 / deg, 1e-12);
  EXPECT_EQ(coordinate_limit_force(f, 0.0, 3.0), 0.0);
  // Fully past the upper limit (5 + 2 degrees): -K (q - limit) - damping qd.
  const double q = 10 * deg, qd = 0.5;
  EXPECT_NEAR(coordinate_limit_force(f, q, qd), -30 / deg * (q - 5 * deg) - 0.01 / deg * qd, 1e-9);
  // Halfway through the transition the stiffness is half on (the quintic step's middle).
  EXPECT_NEAR(coordinate_limit_force(f, 6 * deg, 0.0), -0.5 * 30 / deg * deg, 1e-9);
  // Past the lower limit (-90 - 2 degrees) it pushes back up with 1 N m per degree.
  EXPECT_NEAR(coordinate_limit_force(f, -95 * deg, 0.0), 1 / deg * 5 * deg, 1e-9);
  // The sum over the model lands on the coordinate.
  std::vector<double> qv(r.model.num_coordinates(), 0.0), qdv(qv.size(), 0.0), tau(qv.size(), 0.0);
  qv[f.coordinate] = q;
  add_passive_generalized_forces(r.model, qv.data(), qdv.data(), tau.data());
  EXPECT_NEAR(tau[f.coordinate], -30 / deg * (q - 5 * deg), 1e-9);
}

}  // namespace
