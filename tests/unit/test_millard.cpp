// Millard2012EquilibriumMuscle's curves as OpenSim's SmoothSegmentedFunctionFactory builds them, the
// reader of their properties, and OpenSim's CoordinateLimitForce.
#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <regex>
#include <sstream>

#include "cpgait/activation/actuators.h"
#include "cpgait/capture/actuator_set.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_path.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/degroote_fregly2016.h"
#include "cpgait/muscles/millard2012.h"
#include "cpgait/muscles/rigid_tendon_muscle.h"
#include "cpgait/muscles/muscle_model.h"
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

// Each curve's value is its Bezier segment's y at the root u of x(u) = x to rounding: the lookup
// table's start and its single Newton step stand in for OpenSim's iteration to 100 machine epsilons.
// Reference: bisection on the Bernstein form of the same control points. Sampled densely near the
// joins and around isometric, where u(x) bends most.
TEST(Millard2012, CurveValuesAreTheirBezierRootsToRounding) {
  auto bernstein = [](const std::array<double, 6>& p, double u) {
    const double v = 1 - u;
    return v * v * v * v * v * p[0] + 5 * v * v * v * v * u * p[1] + 10 * v * v * v * u * u * p[2] + 10 * v * v * u * u * u * p[3] +
           5 * v * u * u * u * u * p[4] + u * u * u * u * u * p[5];
  };
  auto reference = [&](const SmoothSegmentedFunction& f, double x) {
    const auto& segs = f.segments();
    std::size_t i = segs.size() - 1;
    for (std::size_t k = 0; k < segs.size(); ++k)
      if (x >= segs[k].x[0] && x < segs[k].x[5]) {
        i = k;
        break;
      }
    double lo = 0, hi = 1;
    for (int it = 0; it < 200; ++it) (bernstein(segs[i].x, 0.5 * (lo + hi)) < x ? lo : hi) = 0.5 * (lo + hi);
    return bernstein(segs[i].y, 0.5 * (lo + hi));
  };
  millard2012::Parameters p;
  const millard2012::Curves c = millard2012::make_curves(p);
  std::mt19937 rng(7);
  for (const SmoothSegmentedFunction* f :
       {&c.active_force_length, &c.force_velocity, &c.force_velocity_inverse, &c.fiber_force_length, &c.tendon_force_length}) {
    std::vector<double> xs;
    for (int i = 0; i <= 20000; ++i) xs.push_back(f->x_begin() + (f->x_end() - f->x_begin()) * i / 20000.0);
    for (const auto& seg : f->segments())
      for (double join : {seg.x[0], seg.x[5]}) {
        std::uniform_real_distribution<double> near(-1e-3, 1e-3);
        for (int i = 0; i < 500; ++i) xs.push_back(std::clamp(join + near(rng), f->x_begin(), f->x_end()));
      }
    double worst = 0;
    for (double x : xs) worst = std::max(worst, std::abs(f->value(x) - reference(*f, x)));
    EXPECT_LT(worst, 1e-13) << "curve from " << f->x_begin() << " to " << f->x_end();
  }
}

// A NaN argument (a state gone bad) gives NaN from every lookup, not an out-of-range table read:
// CMC once crashed here on an uninitialised fibre length.
TEST(Millard2012, CurvesGiveNanForNan) {
  const millard2012::Curves c = millard2012::make_curves(millard2012::Parameters{});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const SmoothSegmentedFunction* f :
       {&c.active_force_length, &c.force_velocity, &c.force_velocity_inverse, &c.fiber_force_length, &c.tendon_force_length}) {
    double y = 0, dydx = 0;
    f->value_and_derivative(nan, y, dydx);
    EXPECT_TRUE(std::isnan(f->value(nan)) && std::isnan(f->derivative(nan)) && std::isnan(y) && std::isnan(dydx))
        << "curve from " << f->x_begin() << " to " << f->x_end();
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

// A pennated Millard muscle with OpenSim's default curves (damped unless said otherwise).
Muscle millard_muscle(double damping = 0.1) {
  Muscle m = refdata::pennate_muscle(1000, 0.1, 0.25, 0.3);
  m.name = "pennated";
  m.max_contraction_velocity = 10;
  millard2012::Parameters p;
  p.fiber_damping = damping;
  m.millard = std::make_shared<const millard2012::Curves>(millard2012::make_curves(p));
  return m;
}

// The compliant fibre's velocity balances the damped fibre force against the tendon's, and it is
// zero at the static equilibrium length; with a slack path the fibre shortens, stretched it lengthens.
TEST(Millard2012, CompliantFibreVelocityBalancesTendonAndFibre) {
  for (double damping : {0.1, 0.0}) {
    const Muscle m = millard_muscle(damping);
    const auto& c = *m.millard;
    const double L = 0.1 * std::cos(0.3) + 0.25 * 1.02;  // fibre near optimal, tendon stretched 2 %
    for (double a : {0.05, 0.3, 1.0}) {
      const double lm = muscles::compliant_equilibrium_fiber_length(m, a, L, 0.0);
      const CompliantTendonFiber still = muscles::compliant_tendon_fiber(m, a, L, lm);
      EXPECT_NEAR(still.fiber_velocity_m_s, 0.0, 1e-6) << a << " " << damping;
      const double lN = lm / 0.1, cos_pen = std::sqrt(1 - std::pow(0.1 * std::sin(0.3) / lm, 2));
      EXPECT_NEAR(still.cos_pennation, cos_pen, 1e-12);
      EXPECT_NEAR(still.force_N, 1000 * (a * c.active_force_length.value(lN) + c.fiber_force_length.value(lN)) * cos_pen,
                  1e-4);
      for (double scale : {0.97, 1.03}) {
        const CompliantTendonFiber f = muscles::compliant_tendon_fiber(m, a, L, lm * scale);
        const double l = lm * scale, n = l / 0.1, vN = f.fiber_velocity_m_s / (0.1 * 10);
        const double cp = std::sqrt(1 - std::pow(0.1 * std::sin(0.3) / l, 2));
        const double fibre = (a * c.active_force_length.value(n) * c.force_velocity.value(vN) + c.fiber_force_length.value(n) +
                              c.parameters.fiber_damping * vN) * cp;
        EXPECT_NEAR(fibre * 1000, f.force_N, 1e-6) << a << " " << scale << " " << damping;
        // A longer fibre leaves the tendon less stretched: the fibre must shorten, and vice versa.
        if (scale > 1) EXPECT_LT(f.fiber_velocity_m_s, 0.0);
        else EXPECT_GT(f.fiber_velocity_m_s, 0.0);
      }
    }
  }
}

// With the tendon at its slack length the rigid-tendon force is the fibre's own: at optimal length
// and no motion a*F0*cos(pennation) active, nothing passive; lengthening adds the damping force.
// The damped fibre's velocity is the one root of its force balance from any starting guess: across
// the force-velocity curve's corner at isometric a plain Newton step cycled between the eccentric and
// concentric sides (CMC's force predictor, warm-started from the last evaluation, met such a cycle
// and tracked 8.5 deg off).
TEST(Millard2012, DampedFibreVelocityIsTheSameFromAnyGuess) {
  const Muscle m = millard_muscle(0.1);
  const double vmax = 0.1 * 10;  // optimal length x max contraction velocity (m/s)
  const double L = 0.1 * std::cos(0.3) + 0.25 * 1.02;
  int compared = 0;
  for (double a : {0.02, 0.18, 0.6, 1.0})
    for (double scale : {0.9, 0.97, 1.0, 1.03, 1.1}) {
      const double lm = muscles::compliant_equilibrium_fiber_length(m, a, L, 0.0) * scale;
      const CompliantTendonFiber reference = muscles::compliant_tendon_fiber(m, a, L, lm);
      for (int k = -20; k <= 20; ++k) {
        const double guess = 0.05 * k;
        const CompliantTendonFiber f = muscles::compliant_tendon_fiber(m, a, L, lm, guess * vmax);
        EXPECT_NEAR(f.fiber_velocity_m_s, reference.fiber_velocity_m_s, 1e-8 * vmax) << a << " " << scale << " " << guess;
        ++compared;
      }
    }
  EXPECT_EQ(compared, 4 * 5 * 41);
}

// One implicit step (CMC's force prediction): the length and velocity returned satisfy the step's
// equation and the fibre's force balance there, as compliant_tendon_fiber finds that velocity for
// that length from scratch; without damping it declines (the caller's own solve then).
TEST(Millard2012, ImplicitFibreStepSolvesTheStepAndTheForceBalance) {
  const Muscle m = millard_muscle(0.1);
  const double vmax = 0.1 * 10;
  int solved = 0;
  for (double a : {0.02, 0.3, 1.0})
    for (double stretch : {1.0, 1.02, 1.04})
      for (double step_s : {5e-4, 1.7e-3})
        for (double v_start : {-0.3, 0.0, 0.2}) {
          const double L = 0.1 * std::cos(0.3) + 0.25 * stretch;
          const double lm0 = muscles::compliant_equilibrium_fiber_length(m, a, L, 0.0);
          const double base = lm0 * 1.01;  // the last length, off the equilibrium
          double l = base + step_s * v_start * vmax, v = v_start * vmax;
          const auto fibre = millard2012::implicit_fiber_step(m, a, L, base, step_s, l, v);
          ASSERT_TRUE(fibre.has_value()) << a << " " << stretch << " " << step_s << " " << v_start;
          EXPECT_NEAR(l, base + step_s * v, 1e-12 * 0.1);
          const CompliantTendonFiber there = muscles::compliant_tendon_fiber(m, a, L, l);
          EXPECT_NEAR(v, there.fiber_velocity_m_s, 1e-8 * vmax) << a << " " << stretch << " " << step_s << " " << v_start;
          EXPECT_NEAR(fibre->fiber_velocity_m_s, v, 1e-15);
          EXPECT_NEAR(fibre->force_N, there.force_N, 1e-6);
          EXPECT_NEAR(fibre->cos_pennation, there.cos_pennation, 1e-9);
          ++solved;
        }
  EXPECT_EQ(solved, 3 * 3 * 2 * 3);
  const Muscle undamped = millard_muscle(0.0);
  double l = 0.1, v = 0.0;
  EXPECT_FALSE(millard2012::implicit_fiber_step(undamped, 0.5, 0.1 * std::cos(0.3) + 0.25, 0.1, 1e-3, l, v).has_value());
  EXPECT_EQ(l, 0.1);
}

TEST(Millard2012, RigidTendonForces) {
  const Muscle m = millard_muscle();
  const double L = 0.1 * std::cos(0.3) + 0.25;
  const RigidTendonForces f = muscles::rigid_tendon_forces(m, 0.5, L, 0.0);
  EXPECT_NEAR(f.active_N, 0.5 * 1000 * std::cos(0.3), 1e-9);
  EXPECT_NEAR(f.passive_N, 0.0, 1e-9);
  EXPECT_NEAR(muscles::rigid_tendon_fiber_length(m, L), 0.1, 1e-12);
  const double V = 0.2;  // m/s along the path
  const RigidTendonForces g = muscles::rigid_tendon_forces(m, 0.5, L, V);
  const double vN = V * std::cos(0.3) / 1.0;
  EXPECT_NEAR(g.active_N, 0.5 * 1000 * m.millard->force_velocity.value(vN) * std::cos(0.3), 1e-9);
  EXPECT_NEAR(g.passive_N, 1000 * 0.1 * vN * std::cos(0.3), 1e-9);
  // Static optimization's force (OpenSim's inextensible-tendon force) evaluates the pennation angle
  // at the normalised length, as OpenSim 4 does: its cosine is that of asin(h / 1.0), not of 0.3.
  const double h = 0.1 * std::sin(0.3);
  EXPECT_NEAR(millard2012::inextensible_tendon_active_force(m, 1.0, L, 0.0), 1000 * std::cos(std::asin(h / 1.0)), 1e-9);
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

// PathSpring (gait10dof18musc's biarticular spring-damper from gastrocnemius origin to calcaneus):
// read as OpenSim defines it, its generalized forces are minus the gradient of its elastic energy
// k/2 max(0, L - L0)^2 (central differences over the path, its conditional point included), and
// dissipation scales the tension by 1 + c dL/dt.
TEST(PathSpring, GeneralizedForcesAreTheEnergysGradientAndDissipationScalesThem) {
  const std::string path = refdata::shared_path("opensim/gait10dof18musc/OutputReference/CMC/subject01_metabolics_path_spring.osim");
  REQUIRE_REFERENCE(path);
  const OsimReadResult r = read_osim(path);
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("PathSpring"), std::string::npos) << w;
  const Model& m = r.model;
  ASSERT_EQ(m.path_springs.size(), 1u);
  const PathSpring& s = m.path_springs[0];
  EXPECT_EQ(s.name, "BiarticularSpringDamper");
  EXPECT_EQ(s.resting_length_m, 0.4);
  EXPECT_EQ(s.stiffness_N_per_m, 10000.0);
  EXPECT_EQ(s.dissipation_s_per_m, 0.01);
  ASSERT_EQ(s.path.size(), 3u);
  EXPECT_EQ(s.path[1].kind, PathPoint::Kind::kConditional);
  EXPECT_EQ(path_spring_tension(s, 0.39, 5.0), 0.0);  // slack: no force, whatever the speed
  EXPECT_NEAR(path_spring_tension(s, 0.45, 2.0), 10000 * 0.05 * (1 + 0.01 * 2.0), 1e-9);

  const int n = m.num_coordinates();
  auto energy = [&](const Eigen::VectorXd& q) {
    KinematicsWorkspace<double> ws(m);
    forward_kinematics(m, q.data(), ws);
    const double stretch = std::max(0.0, path_length(m, s, q.data(), ws) - s.resting_length_m);
    return 0.5 * s.stiffness_N_per_m * stretch * stretch;
  };
  const int knee = m.coordinate_index("knee_angle_r"), ankle = m.coordinate_index("ankle_angle_r");
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int stretched = 0;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd q = Eigen::VectorXd::Zero(n), qd = Eigen::VectorXd::Zero(n), tau = Eigen::VectorXd::Zero(n);
    q[knee] = -0.9 * (u(rng) + 1);  // 0 to -1.8 rad, the conditional point on and off
    q[ankle] = 0.5 * u(rng);
    add_passive_generalized_forces(m, q.data(), qd.data(), tau.data());
    if (energy(q) > 0) ++stretched;
    for (int c : {knee, ankle}) {
      const double h = 1e-7;
      Eigen::VectorXd qp = q, qm = q;
      qp[c] += h;
      qm[c] -= h;
      EXPECT_NEAR(tau[c], -(energy(qp) - energy(qm)) / (2 * h), 1e-4 * (1 + std::abs(tau[c]))) << m.coordinates[c].name;
    }
    // Moving: the tension, and so every generalized force, grows by 1 + c dL/dt.
    qd[knee] = 2.0 * u(rng);
    qd[ankle] = 3.0 * u(rng);
    Eigen::VectorXd tau_moving = Eigen::VectorXd::Zero(n);
    add_passive_generalized_forces(m, q.data(), qd.data(), tau_moving.data());
    KinematicsWorkspace<double> ws(m);
    const double dt = 1e-7;
    Eigen::VectorXd q1 = q + dt * qd, q0 = q - dt * qd;
    forward_kinematics(m, q1.data(), ws);
    const double l1 = path_length(m, s, q1.data(), ws);
    forward_kinematics(m, q0.data(), ws);
    const double speed = (l1 - path_length(m, s, q0.data(), ws)) / (2 * dt);
    for (int c : {knee, ankle}) EXPECT_NEAR(tau_moving[c], tau[c] * (1 + s.dissipation_s_per_m * speed), 1e-4 * (1 + std::abs(tau[c])));
  }
  EXPECT_GE(stretched, 5);  // the comparisons above included a loaded spring
}

// PathActuator (gait10dof18musc's PlantarFlexAssist, tibia to calcaneus): read from the model's
// ForceSet with the other actuators, its generalized forces at control 1 are -optimal_force dL/dq
// (central differences of its path's length) on the coordinates it spans and zero elsewhere.
TEST(PathActuator, GeneralizedForcesAreTheTensionTimesMinusThePathsGradient) {
  const std::string path = refdata::shared_path("opensim/gait10dof18musc/OutputReference/CMC/subject01_metabolics_path_actuator.osim");
  REQUIRE_REFERENCE(path);
  const OsimReadResult r = read_osim(path);
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("PathActuator"), std::string::npos) << w;
  const Model& m = r.model;
  ASSERT_EQ(m.path_actuators.size(), 1u);
  ASSERT_EQ(m.path_actuators[0].path.size(), 2u);
  std::vector<ActuatorSpec> specs;
  for (const ActuatorSpec& a : read_actuators(path))
    if (a.kind == ActuatorSpec::Kind::kPath) specs.push_back(a);
  ASSERT_EQ(specs.size(), 1u);
  EXPECT_EQ(specs[0].name, "PlantarFlexAssist");
  EXPECT_EQ(specs[0].optimal_force, 10.0);
  EXPECT_EQ(specs[0].min_control, -std::numeric_limits<double>::infinity());
  const ResolvedActuators acts(m, specs);

  const int n = m.num_coordinates();
  const PathActuator& pa = m.path_actuators[0];
  auto length = [&](const Eigen::VectorXd& q) {
    KinematicsWorkspace<double> ws(m);
    forward_kinematics(m, q.data(), ws);
    return path_length(m, pa, q.data(), ws);
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int ankle = m.coordinate_index("ankle_angle_r");
  double largest_ankle = 0;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd q = 0.5 * Eigen::VectorXd::NullaryExpr(n, [&] { return u(rng); });
    KinematicsWorkspace<double> ws(m);
    MotionSubspace S(m);
    forward_kinematics(m, q.data(), ws);
    motion_subspace(m, q.data(), ws, S);
    Eigen::MatrixXd G(n, 1);
    acts.generalized_forces(m, q.data(), ws, S, G);
    for (int c = 0; c < n; ++c) {
      const double h = 1e-7;
      Eigen::VectorXd qp = q, qm = q;
      qp[c] += h;
      qm[c] -= h;
      EXPECT_NEAR(G(c, 0), -10.0 * (length(qp) - length(qm)) / (2 * h), 1e-6) << m.coordinates[c].name;
    }
    largest_ankle = std::max(largest_ankle, std::abs(G(ankle, 0)));
  }
  EXPECT_GT(largest_ankle, 0.1);  // it acts on the ankle (10 N over a few centimetres of moment arm)

  // A PathActuator whose path the model does not hold is refused naming it.
  ActuatorSpec stray = specs[0];
  stray.name = "NotInTheModel";
  try {
    ResolvedActuators bad(m, {stray});
    ADD_FAILURE() << "accepted a path actuator with no path";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("NotInTheModel"), std::string::npos) << e.what();
  }
}

// The walker fixture's document with `forces` (XML) first in its ForceSet.
std::string walker_with_forces(const std::string& forces) {
  std::string doc = text::read_file(refdata::fixture("models/walker.osim"));
  const std::size_t at = doc.find("<objects>", doc.find("<ForceSet"));
  if (at == std::string::npos) throw std::runtime_error("walker.osim has no ForceSet objects");
  return doc.insert(at + 9, forces);
}

// SpringGeneralizedForce: -stiffness (q - rest_length) - viscosity qdot on its coordinate, in the
// coordinate's own units as OpenSim applies it; a disabled one applies nothing.
TEST(SpringGeneralizedForce, PullsItsCoordinateTowardsRestAndDamps) {
  const std::string doc = walker_with_forces(
             "<SpringGeneralizedForce name=\"knee_spring\"><coordinate>knee_angle_r</coordinate><stiffness>50</stiffness>"
             "<rest_length>0.2</rest_length><viscosity>3</viscosity></SpringGeneralizedForce>"
             "<SpringGeneralizedForce name=\"off\"><appliesForce>false</appliesForce><coordinate>knee_angle_l</coordinate>"
             "<stiffness>50</stiffness></SpringGeneralizedForce>");
  const OsimReadResult r = parse_osim(doc, "walker_spring.osim");
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("SpringGeneralizedForce"), std::string::npos) << w;
  ASSERT_EQ(r.model.spring_generalized_forces.size(), 1u);
  const int knee = r.model.coordinate_index("knee_angle_r");
  std::vector<double> q(r.model.num_coordinates(), 0.0), qd(q.size(), 0.0), tau(q.size(), 0.0);
  q[knee] = -0.5;
  qd[knee] = 2.0;
  q[r.model.coordinate_index("knee_angle_l")] = -0.5;
  add_passive_generalized_forces(r.model, q.data(), qd.data(), tau.data());
  EXPECT_NEAR(tau[knee], -50 * (-0.5 - 0.2) - 3 * 2.0, 1e-12);
  for (std::size_t c = 0; c < tau.size(); ++c) {
    if (static_cast<int>(c) == knee) continue;
    EXPECT_EQ(tau[c], 0.0) << r.model.coordinates[c].name;
  }
  // An unknown coordinate names the force and the line.
  std::string bad = doc;
  bad.replace(bad.find("<coordinate>knee_angle_r"), 24, "<coordinate>knee_angle_x");
  try {
    parse_osim(bad, "walker_spring.osim");
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("knee_spring"), std::string::npos) << e.what();
    EXPECT_GT(e.line(), 0);
  }
}

// ExpressionBasedCoordinateForce: its expression in q and qdot (Lepton's grammar) is the generalized
// force on its coordinate; one written as a spring equals the SpringGeneralizedForce of the same
// constants; an expression that does not parse names the file, the line and the token.
TEST(ExpressionBasedCoordinateForce, AppliesItsExpressionOnItsCoordinate) {
  const std::string doc = walker_with_forces(
             "<ExpressionBasedCoordinateForce name=\"knee_expr\"><coordinate>knee_angle_r</coordinate>\n"
             "<expression>-50*(q-0.2) - 3*qdot + 0.1*max(0, -q)^2</expression></ExpressionBasedCoordinateForce>"
             "<SpringGeneralizedForce name=\"hip_spring\"><coordinate>hip_flexion_l</coordinate><stiffness>40</stiffness>"
             "<rest_length>0.1</rest_length><viscosity>2</viscosity></SpringGeneralizedForce>"
             "<ExpressionBasedCoordinateForce name=\"hip_expr\"><coordinate>hip_flexion_r</coordinate>"
             "<expression>-k*(q-rest)-2*qdot; k=40; rest=0.1</expression></ExpressionBasedCoordinateForce>");
  const OsimReadResult r = parse_osim(doc, "walker_expr.osim");
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("ExpressionBased"), std::string::npos) << w;
  ASSERT_EQ(r.model.expression_based_coordinate_forces.size(), 2u);
  const Model& m = r.model;
  const int knee = m.coordinate_index("knee_angle_r"), hip_r = m.coordinate_index("hip_flexion_r"), hip_l = m.coordinate_index("hip_flexion_l");
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 10; ++trial) {
    std::vector<double> q(m.num_coordinates(), 0.0), qd(q.size(), 0.0), tau(q.size(), 0.0);
    for (std::size_t c = 0; c < q.size(); ++c) {
      q[c] = u(rng);
      qd[c] = 3 * u(rng);
    }
    q[hip_l] = q[hip_r];
    qd[hip_l] = qd[hip_r];
    add_passive_generalized_forces(m, q.data(), qd.data(), tau.data());
    EXPECT_NEAR(tau[knee], -50 * (q[knee] - 0.2) - 3 * qd[knee] + 0.1 * std::pow(std::max(0.0, -q[knee]), 2), 1e-12);
    EXPECT_NEAR(tau[hip_r], tau[hip_l], 1e-12);
    for (std::size_t c = 0; c < tau.size(); ++c) {
      if (static_cast<int>(c) != knee && static_cast<int>(c) != hip_r && static_cast<int>(c) != hip_l) {
        EXPECT_EQ(tau[c], 0.0);
      }
    }
  }
  std::string bad = doc;
  bad.replace(bad.find("3*qdot"), 6, "3*qdt ");
  try {
    parse_osim(bad, "walker_expr.osim");
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown variable 'qdt'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("walker_expr.osim"), std::string::npos) << e.what();
    EXPECT_GT(e.line(), 0);
  }
}

}  // namespace

// DeGrooteFregly2016Muscle's closed-form curves at their defining points (OpenSim's constants): the
// active curve peaks near optimal length, the force-velocity curve is 1 at rest and its inverse
// undoes it, passive and tendon forces reach 1 at their strains at one normalised force (and the
// tendon's is zero at slack length).
TEST(DeGrooteFregly2016, CurvesHaveTheirDefiningValues) {
  degroote_fregly2016::Parameters p;
  EXPECT_NEAR(degroote_fregly2016::active_force_length(p, 1.0), 1.0, 2e-3);
  EXPECT_LT(degroote_fregly2016::active_force_length(p, 0.5), 0.3);
  EXPECT_NEAR(degroote_fregly2016::force_velocity(0.0), 1.0, 1e-9);
  EXPECT_NEAR(degroote_fregly2016::force_velocity(-1.0), 0.0, 0.02);
  for (double v : {-0.9, -0.3, 0.0, 0.4, 0.9})
    EXPECT_NEAR(degroote_fregly2016::force_velocity_inverse(degroote_fregly2016::force_velocity(v)), v, 1e-12);
  EXPECT_NEAR(degroote_fregly2016::passive_force_length(p, 1.6), 1.0, 1e-12);
  EXPECT_NEAR(degroote_fregly2016::passive_force_length(p, 0.2), 0.0, 1e-12);
  EXPECT_NEAR(degroote_fregly2016::tendon_force_length(p, 1.0), 0.0, 1e-12);
  EXPECT_NEAR(degroote_fregly2016::tendon_force_length(p, 1.049), 1.0, 1e-12);
  p.ignore_passive_fiber_force = true;
  EXPECT_EQ(degroote_fregly2016::passive_force_length(p, 1.5), 0.0);
  p.active_force_width_scale = 2.0;  // twice as wide: the value at 1 + 2 d is the default's at 1 + d
  degroote_fregly2016::Parameters q;
  EXPECT_NEAR(degroote_fregly2016::active_force_length(p, 1.4), degroote_fregly2016::active_force_length(q, 1.2), 1e-12);
}

// A DeGroote muscle's compliant fibre is at rest at its equilibrium length, and its activation rises
// with OpenSim's blend of the two time constants (faster than deactivation's, slower than activation's
// alone at a = 0.5).
TEST(DeGrooteFregly2016, EquilibriumAndActivation) {
  Muscle m = refdata::pennate_muscle(800, 0.1, 0.2, 0.2);
  m.activation_time_constant_s = 0.015;
  m.deactivation_time_constant_s = 0.060;
  m.min_control = 0;
  m.degroote = std::make_shared<const degroote_fregly2016::Parameters>();
  const double L = 0.1 * std::cos(0.2) + 0.2 * 1.01;
  for (double a : {0.1, 0.6}) {
    const double lm = muscles::compliant_equilibrium_fiber_length(m, a, L, 0.0);
    EXPECT_NEAR(muscles::compliant_tendon_fiber(m, a, L, lm).fiber_velocity_m_s, 0.0, 1e-6);
    EXPECT_GT(muscles::compliant_tendon_fiber(m, a, L, lm * 1.02).fiber_velocity_m_s, -10.0);
    EXPECT_LT(muscles::compliant_tendon_fiber(m, a, L, lm * 1.02).fiber_velocity_m_s, 0.0);
  }
  const double rate = thelen_activation_rate(m, 1.0, 0.5);  // z = 1.25, f = 0.5 tanh(0.05)
  const double z = 1.25, f = 0.5 * std::tanh(0.05);
  EXPECT_NEAR(rate, ((f + 0.5) / (0.015 * z) + (0.5 - f) * z / 0.060) * 0.5, 1e-12);
}

// RigidTendonMuscle: OpenSim's default curves, the fibre moving at the path's speed, and an
// activation that follows the control at once.
TEST(RigidTendonMuscle, ForcesFromItsCurves) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/CMC/block_hanging_RigidTendonMuscle.osim");
  REQUIRE_REFERENCE(path);
  const OsimReadResult r = read_osim(path);
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("not supported"), std::string::npos) << w;
  ASSERT_EQ(r.model.muscles.size(), 1u);
  const Muscle& mu = r.model.muscles[0];
  ASSERT_TRUE(mu.rigid_tendon);
  EXPECT_TRUE(muscles::has_rigid_tendon(mu));
  const double L = mu.tendon_slack_length_m + mu.optimal_fiber_length_m * std::cos(mu.pennation_angle_at_optimal_rad);
  const RigidTendonForces f = muscles::rigid_tendon_forces(mu, 0.7, L, 0.0);
  const double cos_pen = std::cos(mu.pennation_angle_at_optimal_rad);
  EXPECT_NEAR(f.active_N, 0.7 * mu.max_isometric_force_N * mu.rigid_tendon->active_force_length.value(1.0) * cos_pen, 1e-9);
  EXPECT_NEAR(f.passive_N, 0.0, 1e-9);
  // Shortening at a tenth of max speed: the force-velocity curve's value there (0.642857 at -0.1).
  const double V = -0.1 * mu.optimal_fiber_length_m * mu.max_contraction_velocity;
  EXPECT_NEAR(muscles::rigid_tendon_forces(mu, 0.7, L, V).active_N / f.active_N, 0.642857, 1e-6);
  EXPECT_NEAR(thelen_activation_rate(mu, 0.8, 0.3), 0.5 / 1e-3, 1e-9);
}
