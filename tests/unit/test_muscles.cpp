#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/muscle_path.h"
#include "cpgait/muscles/scale_muscle_parameters.h"
#include "cpgait/muscles/thelen2003.h"
#include "test_support.h"

using namespace cpgait;

namespace {


// Moment arms three ways: analytic (motion subspace), forward-mode autodiff through path_length,
// and central differences of the path length. Half the poses put a conditional point's coordinate
// just inside or just outside its range, where the path changes.
void check_moment_arms(const Model& m, int poses) {
  constexpr int N = 32;
  using Jet = ceres::Jet<double, N>;
  ASSERT_LE(m.num_coordinates(), N);
  std::mt19937 rng(21);
  KinematicsWorkspace<double> ws(m);
  KinematicsWorkspace<Jet> wj(m);
  MotionSubspace S(m);
  MusclePathGeometry g(m);
  std::vector<std::pair<int, double>> switches;  // coordinate, boundary
  for (const auto& mu : m.muscles)
    for (const auto& p : mu.path)
      if (p.kind == PathPoint::Kind::kConditional) switches.push_back({p.coordinate, p.range_min}), switches.push_back({p.coordinate, p.range_max});
  int near_switch = 0;
  for (int t = 0; t < poses; ++t) {
    Eigen::VectorXd q = refdata::random_pose(m, rng, 2.0);
    if (t % 2 == 1 && !switches.empty()) {
      const auto [c, edge] = switches[rng() % switches.size()];
      q[c] = edge + (t % 4 == 1 ? 1e-4 : -1e-4);  // FD steps below stay on one side
      ++near_switch;
    }
    const Eigen::VectorXd qd = Eigen::VectorXd::Random(m.num_coordinates());
    forward_kinematics(m, q.data(), ws);
    motion_subspace(m, q.data(), ws, S);
    muscle_path_geometry(m, q.data(), qd.data(), ws, S, g);
    std::vector<Jet> qj(m.num_coordinates());
    for (int c = 0; c < m.num_coordinates(); ++c) qj[c] = Jet(q[c], c);
    forward_kinematics(m, qj.data(), wj);
    for (std::size_t k = 0; k < m.muscles.size(); ++k) {
      const Jet L = path_length(m, m.muscles[k], qj.data(), wj);
      EXPECT_NEAR(L.a, g.length_m[k], 1e-12) << m.muscles[k].name;
      for (int c = 0; c < m.num_coordinates(); ++c) {
        EXPECT_NEAR(g.moment_arm_m(k, c), -L.v[c], 1e-10) << m.muscles[k].name << " about " << m.coordinates[c].name;
        const double h = 1e-6;
        Eigen::VectorXd qp = q, qm = q;
        qp[c] += h;
        qm[c] -= h;
        forward_kinematics(m, qp.data(), ws);
        const double Lp = path_length(m, m.muscles[k], qp.data(), ws);
        forward_kinematics(m, qm.data(), ws);
        const double Lm = path_length(m, m.muscles[k], qm.data(), ws);
        EXPECT_NEAR(g.moment_arm_m(k, c), -(Lp - Lm) / (2 * h), 1e-7) << m.muscles[k].name << " about " << m.coordinates[c].name;
      }
      EXPECT_NEAR(g.lengthening_speed_m_s[k], -g.moment_arm_m.row(k).dot(qd), 1e-12);
    }
  }
  EXPECT_GT(near_switch, 0);
}

const Muscle& vastus() { return refdata::walker().muscles[0]; }

}  // namespace

TEST(MusclePath, MomentArmsOnFixtureModel) { check_moment_arms(read_osim(refdata::fixture("models/walker.osim")).model, 16); }

// A moving point in the middle of a path (gait2392's and the walker's come last): the walker's
// vastus gains a fixed point on the tibia after its moving patella point, so both ends of a segment
// move with the knee through the point's functions.
TEST(MusclePath, MomentArmsWithAMovingPointMidPath) {
  Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  Muscle& vas = m.muscles[0];
  ASSERT_EQ(vas.path.back().kind, PathPoint::Kind::kMoving);
  PathPoint distal;
  distal.name = "distal";
  distal.body = vas.path.back().body;
  distal.location_m = Eigen::Vector3d(0.01, -0.12, 0.0);
  vas.path.push_back(distal);
  check_moment_arms(m, 16);
}

// OpenSim's paths run from origin to insertion, proximal to distal; the same path given the other
// way round has the same length and moment arms (the branch of the chain walk for a point on a deeper
// body than the next one runs only then).
TEST(MusclePath, APathGivenFromInsertionToOriginHasTheSameMomentArms) {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  Model reversed = m;
  for (Muscle& mu : reversed.muscles) std::reverse(mu.path.begin(), mu.path.end());
  check_moment_arms(reversed, 8);
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  MusclePathGeometry g(m), gr(m);
  std::mt19937 rng(5);
  for (int t = 0; t < 8; ++t) {
    const Eigen::VectorXd q = refdata::random_pose(m, rng, 2.0), qd = Eigen::VectorXd::Ones(m.num_coordinates());
    forward_kinematics(m, q.data(), ws);
    motion_subspace(m, q.data(), ws, S);
    muscle_path_geometry(m, q.data(), qd.data(), ws, S, g);
    muscle_path_geometry(reversed, q.data(), qd.data(), ws, S, gr);
    EXPECT_LT((g.length_m - gr.length_m).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LT((g.moment_arm_m - gr.moment_arm_m).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_GT(g.moment_arm_m.cwiseAbs().maxCoeff(), 0.01);
  }
}

TEST(MusclePathReference, MomentArmsOnGait2392) {
  const std::string path = refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(path);
  check_moment_arms(read_osim(path).model, 4);
}

// Outside spanned_coordinates a moment arm is exactly zero at any pose (the Jacobian of the muscle-driven
// dynamics looks for nonzero ones only there), on the walker, arm26 (wrap cylinders), gait2392
// (moving and conditional points) and gait10dof18musc; on the reference models the set is tight: at
// a random pose every spanned coordinate but a few has a nonzero moment arm.
TEST(MusclePath, MomentArmsAreZeroOutsideTheSpannedCoordinates) {
  const Model walker = read_osim(refdata::fixture("models/walker.osim")).model;
  const Muscle& vas = walker.muscles[0];  // femur to tibia, with a moving patella point on the knee
  EXPECT_EQ(spanned_coordinates(walker, vas), std::vector<int>{walker.coordinate_index("knee_angle_r")});
  std::vector<std::string> files{refdata::shared_path("opensim/opensim-core-tests/Analyze/arm26.osim"),
                                 refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim"),
                                 refdata::shared_path("opensim/gait10dof18musc/OutputReference/subject01.osim")};
  std::mt19937 rng(17);
  for (const std::string& file : files) {
    if (!std::filesystem::exists(file)) {
      std::printf("[ skip ] reference data absent: %s\n", file.c_str());
      continue;
    }
    const Model m = read_osim(file).model;
    KinematicsWorkspace<double> ws(m);
    MotionSubspace S(m);
    MusclePathGeometry g(m);
    std::vector<std::vector<int>> spanned;
    for (const Muscle& mu : m.muscles) spanned.push_back(spanned_coordinates(m, mu));
    int spanned_entries = 0, nonzero = 0;
    for (int t = 0; t < 20; ++t) {
      const Eigen::VectorXd q = refdata::random_pose(m, rng, 2.0), qd = Eigen::VectorXd::Ones(m.num_coordinates());
      forward_kinematics(m, q.data(), ws);
      motion_subspace(m, q.data(), ws, S);
      muscle_path_geometry(m, q.data(), qd.data(), ws, S, g);
      for (std::size_t k = 0; k < m.muscles.size(); ++k) {
        const std::vector<int>& span = spanned[k];
        ASSERT_TRUE(std::is_sorted(span.begin(), span.end()));
        for (int c = 0; c < m.num_coordinates(); ++c) {
          const bool in = std::binary_search(span.begin(), span.end(), c);
          if (!in) {
            EXPECT_EQ(g.moment_arm_m(k, c), 0.0) << file << ": " << m.muscles[k].name << " about " << m.coordinates[c].name;
          }
          spanned_entries += in;
          nonzero += in && g.moment_arm_m(k, c) != 0;
        }
      }
    }
    std::printf("[ info ] %s: %d of %d spanned entries nonzero over 20 poses\n", file.c_str(), nonzero, spanned_entries);
    EXPECT_GT(nonzero, 0.9 * spanned_entries) << file;
  }
}

TEST(MusclePath, ConditionalPointSwitchesWithItsCoordinate) {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  const Muscle& vas = m.muscles[0];  // P2 active for knee in [-2.6, -1.42]
  ASSERT_EQ(vas.path[1].kind, PathPoint::Kind::kConditional);
  KinematicsWorkspace<double> ws(m);
  Eigen::VectorXd q = m.default_coordinates();
  const int knee = m.coordinate_index("knee_angle_r");
  auto length = [&](double k) {
    q[knee] = k;
    forward_kinematics(m, q.data(), ws);
    return path_length(m, vas, q.data(), ws);
  };
  // Inside the range the path goes through P2, so it is longer than the straight line P1-P3; outside
  // it is that straight line.
  auto straight = [&](double k) {
    q[knee] = k;
    forward_kinematics(m, q.data(), ws);
    auto at = [&](const PathPoint& p) {
      const auto& B = ws.body_in_ground[p.body];
      return Eigen::Vector3d(B.rotation * path_point_location(p, q.data()) + B.translation_m);
    };
    return (at(vas.path[2]) - at(vas.path[0])).norm();
  };
  ASSERT_EQ(vas.path.size(), 3u);
  const double inside = length(-1.5), outside = length(-1.3);
  EXPECT_TRUE(path_point_active(vas.path[1], -1.5));
  EXPECT_FALSE(path_point_active(vas.path[1], -1.3));
  EXPECT_GT(inside, straight(-1.5) + 1e-4);
  EXPECT_NEAR(outside, straight(-1.3), 1e-12);
}

TEST(Thelen2003, CurvesHaveTheirDefiningValues) {
  const Muscle& m = vastus();
  EXPECT_DOUBLE_EQ(thelen2003::active_force_length(m, 1.0), 1.0);
  EXPECT_NEAR(thelen2003::active_force_length(m, 1.0 + std::sqrt(m.kshape_active)), std::exp(-1.0), 1e-15);
  EXPECT_DOUBLE_EQ(thelen2003::passive_force_length(m, 1.0), 0.0);
  EXPECT_NEAR(thelen2003::passive_force_length(m, 1.0 + m.fmax_muscle_strain), 1.0, 1e-12);  // F0 at max strain
  EXPECT_NEAR(thelen2003::tendon_force_strain(m, 1.0 + m.fmax_tendon_strain), 1.0, 1e-12);   // F0 at e0
  EXPECT_DOUBLE_EQ(thelen2003::tendon_force_strain(m, 0.99), 0.0);
  // Force-velocity: isometric = 1; the inverse undoes fiber_velocity across all regions,
  // including both linear extrapolations.
  for (double a : {0.05, 0.5, 1.0}) {
    const double fal = 0.8;
    EXPECT_NEAR(thelen2003::force_velocity_multiplier(m, a, fal, 0.0), 1.0, 1e-12);
    for (double v = -2.0; v <= 2.0; v += 0.01) {
      const double fv = thelen2003::force_velocity_multiplier(m, a, fal, v);
      EXPECT_NEAR(thelen2003::fiber_velocity(m, a, fal, a * fal * fv), v, 1e-10) << "a=" << a << " v=" << v;
    }
    // Shortening lowers force, lengthening raises it toward Flen.
    EXPECT_LT(thelen2003::force_velocity_multiplier(m, a, fal, -0.1), 1.0);
    EXPECT_GT(thelen2003::force_velocity_multiplier(m, a, fal, 0.1), 1.0);
    EXPECT_LT(thelen2003::force_velocity_multiplier(m, a, fal, 0.1), m.flen);
  }
}

TEST(Thelen2003, RigidTendonForceAtOptimalLength) {
  const Muscle& m = vastus();
  // Path long enough that the fibre sits at its optimal length: along-tendon part lopt*cos(a0).
  const double L = m.tendon_slack_length_m + m.optimal_fiber_length_m * std::cos(m.pennation_angle_at_optimal_rad);
  const auto f = thelen2003::rigid_tendon_fiber(m, L, 0.0);
  EXPECT_NEAR(f.fiber_length_m, m.optimal_fiber_length_m, 1e-12);
  EXPECT_NEAR(thelen2003::rigid_tendon_active_force(m, 1.0, L, 0.0),
              m.max_isometric_force_N * std::cos(m.pennation_angle_at_optimal_rad), 1e-9);
  EXPECT_NEAR(thelen2003::rigid_tendon_active_force(m, 0.3, L, 0.0), 0.3 * thelen2003::rigid_tendon_active_force(m, 1.0, L, 0.0), 1e-9);
  // Activation is clamped to OpenSim's minimum of 0.01.
  EXPECT_NEAR(thelen2003::rigid_tendon_active_force(m, 0.0, L, 0.0), 0.01 * thelen2003::rigid_tendon_active_force(m, 1.0, L, 0.0), 1e-9);
  EXPECT_LT(thelen2003::rigid_tendon_active_force(m, 1.0, L, -0.2), thelen2003::rigid_tendon_active_force(m, 1.0, L, 0.0));
  // Both forces at once are the two functions' (one fibre geometry instead of two), stretched too.
  for (double stretch : {0.0, 0.02, 0.05})
    for (double V : {-0.3, 0.0, 0.2}) {
      const auto both = thelen2003::rigid_tendon_forces(m, 0.4, L + stretch, V);
      EXPECT_DOUBLE_EQ(both.active_N, thelen2003::rigid_tendon_active_force(m, 0.4, L + stretch, V));
      EXPECT_DOUBLE_EQ(both.passive_N, thelen2003::rigid_tendon_passive_force(m, L + stretch));
    }
  EXPECT_GT(thelen2003::rigid_tendon_forces(m, 0.4, L + 0.05, 0.0).passive_N, 0.0);
}

// Thelen's activation dynamics: a step of excitation is followed at the rates the time constants set
// (faster up than down), and the excitation is clamped to the muscle's control range.
TEST(ActivationDynamics, StepResponsesFollowTheTimeConstants) {
  Muscle m;
  m.activation_time_constant_s = 0.015;
  m.deactivation_time_constant_s = 0.060;
  m.min_control = 0.01;
  auto simulate = [&](double a, double u, double duration) {
    const double dt = 1e-5;
    for (double t = 0; t < duration; t += dt) a += dt * thelen_activation_rate(m, u, a);
    return a;
  };
  // Up: at a = 0.01 the time constant is 0.015 * 0.515 s; 63 % of the way within roughly 2-3 of the
  // state-dependent time constants (it grows as a rises).
  const double up = simulate(0.01, 1.0, 0.02);
  const double down = simulate(1.0, 0.0, 0.02);
  EXPECT_GT(up, 0.63);
  EXPECT_GT(down, 0.37);        // deactivation is slower: after 20 ms it has fallen less than 63 %...
  EXPECT_LT(1.0 - down, up);    // ...than activation rose
  EXPECT_NEAR(simulate(0.5, 0.0, 2.0), 0.01, 1e-6);  // settles at min_control, not 0
  EXPECT_NEAR(simulate(0.5, 3.0, 1.0), 1.0, 1e-6);   // excitation clamped at max_control
  // The rate at a = u is zero; its sign follows u - a.
  EXPECT_DOUBLE_EQ(thelen_activation_rate(m, 0.3, 0.3), 0.0);
  EXPECT_GT(thelen_activation_rate(m, 0.4, 0.3), 0.0);
  EXPECT_LT(thelen_activation_rate(m, 0.2, 0.3), 0.0);
  // Up from 0.3 to 0.4: tau_act (0.5 + 1.5 * 0.3) = 0.01425 s.
  EXPECT_NEAR(thelen_activation_rate(m, 0.4, 0.3), 0.1 / (0.015 * 0.95), 1e-12);
  EXPECT_NEAR(thelen_activation_rate(m, 0.2, 0.3), -0.1 / (0.060 / 0.95), 1e-12);
}

// OpenSim's ScaleTool for muscles: a model whose fixed path points were moved outwards (a bigger
// subject) without its muscle lengths gets them scaled by each path's length ratio at the default
// pose, so its normalized fibre lengths there are the generic model's again; a muscle the generic
// model lacks is left alone and named.
TEST(ScaleMuscleParameters, RestoresTheGenericNormalizedFiberLengths) {
  const Model generic = read_osim(refdata::fixture("models/walker.osim")).model;
  ASSERT_GT(generic.muscles.size(), 4u);
  Model bigger = generic;
  for (auto& mu : bigger.muscles)
    for (auto& p : mu.path)
      if (p.kind == PathPoint::Kind::kFixed) p.location_m *= 1.15;
  bigger.muscles.back().name = "only_in_scaled";
  MuscleScalingSummary s;
  const Model scaled = scale_muscle_parameters(bigger, generic, &s);
  EXPECT_EQ(s.muscles_scaled, static_cast<int>(generic.muscles.size()) - 1);
  ASSERT_EQ(s.not_in_generic.size(), 1u);
  EXPECT_EQ(s.not_in_generic[0], "only_in_scaled");
  EXPECT_GT(s.largest_ratio - s.smallest_ratio, 0.01);
  const std::vector<double> before = normalized_fiber_lengths_at_default_pose(generic);
  const std::vector<double> moved = normalized_fiber_lengths_at_default_pose(bigger);
  const std::vector<double> after = normalized_fiber_lengths_at_default_pose(scaled);
  double moved_off = 0;
  for (std::size_t m = 0; m + 1 < generic.muscles.size(); ++m) {
    EXPECT_NEAR(after[m], before[m], 1e-12) << generic.muscles[m].name;
    moved_off = std::max(moved_off, std::abs(moved[m] - before[m]));
    // Both lengths by the same ratio: their proportion stays.
    EXPECT_NEAR(scaled.muscles[m].tendon_slack_length_m / scaled.muscles[m].optimal_fiber_length_m,
                generic.muscles[m].tendon_slack_length_m / generic.muscles[m].optimal_fiber_length_m, 1e-12);
  }
  EXPECT_GT(moved_off, 0.05);  // the moved points did put the fibres elsewhere
  EXPECT_EQ(scaled.muscles.back().optimal_fiber_length_m, bigger.muscles.back().optimal_fiber_length_m);
}
