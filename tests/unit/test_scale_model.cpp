// scale_model's rules that the gait2392 reference (tests/reference/test_scale_gait2392.cpp) does not
// reach - wrap objects, whose dimensions OpenSim scales along the shape's own axes - and forward
// kinematics with body scales against it.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_path.h"
#include "cpgait/scaling/scale_model.h"
#include "test_support.h"

using namespace cpgait;

TEST(ScaleModel, WrapObjectsScaleAlongTheirOwnAxes) {
  Model m;
  m.bodies.resize(2);  // ground and one body; names do not matter here
  auto add = [&](WrapObject::Shape shape, const Eigen::Matrix3d& rotation) {
    WrapObject w;
    w.shape = shape;
    w.body = 1;
    w.pose.rotation = rotation;
    w.pose.translation_m = Eigen::Vector3d(0.1, 0.2, 0.3);
    w.radius_m = 0.05;
    w.length_m = 0.2;
    w.dimensions_m = Eigen::Vector3d(0.01, 0.02, 0.03);
    m.wrap_objects.push_back(w);
  };
  // A cylinder turned 90 deg about x: its y axis is the body's z, its axis (z) the body's -y.
  const Eigen::Matrix3d turned = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  add(WrapObject::Shape::kCylinder, turned);
  add(WrapObject::Shape::kSphere, turned);
  add(WrapObject::Shape::kEllipsoid, Eigen::Matrix3d::Identity());
  add(WrapObject::Shape::kEllipsoid, turned);
  add(WrapObject::Shape::kTorus, turned);
  const std::vector<Eigen::Vector3d> f{Eigen::Vector3d::Ones(), Eigen::Vector3d(1.1, 1.2, 1.3)};
  const Model s = scale_model(m, f, false, -1);
  for (const auto& w : s.wrap_objects) EXPECT_TRUE(w.pose.translation_m.isApprox(Eigen::Vector3d(0.11, 0.24, 0.39), 1e-15));
  // Cylinder: radius by the mean of its x and y axes' factors (1.1, 1.3), length by its z's (1.2).
  EXPECT_NEAR(s.wrap_objects[0].radius_m, 0.05 * 1.2, 1e-15);
  EXPECT_NEAR(s.wrap_objects[0].length_m, 0.2 * 1.2, 1e-15);
  // Sphere: by the mean factor, whatever its orientation.
  EXPECT_NEAR(s.wrap_objects[1].radius_m, 0.05 * 1.2, 1e-15);
  // Ellipsoid: each radius by its axis's factor.
  EXPECT_TRUE(s.wrap_objects[2].dimensions_m.isApprox(Eigen::Vector3d(0.011, 0.024, 0.039), 1e-15));
  EXPECT_TRUE(s.wrap_objects[3].dimensions_m.isApprox(Eigen::Vector3d(0.011, 0.026, 0.036), 1e-15));
  // Torus (axis z): both radii by the mean of its x and y axes' factors, as the cylinder's radius.
  EXPECT_NEAR(s.wrap_objects[4].inner_radius_m, 0.01 * 1.2, 1e-15);
  EXPECT_NEAR(s.wrap_objects[4].outer_radius_m, 0.05 * 1.2, 1e-15);
}

// Forward kinematics given body scales places every body where it is on the model scale_model
// scales (the automatic scale fit differentiates the former): the walker, whose knee translations
// follow the knee angle, with uneven factors at random poses.
TEST(ScaleModel, ScaledForwardKinematicsIsTheScaledModels) {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.8, 1.25), angle(-0.8, 0.8);
  std::vector<Eigen::Vector3d> f(m.bodies.size());
  for (auto& v : f) v = Eigen::Vector3d(u(rng), u(rng), u(rng));
  const Model scaled = scale_model(m, f, false, -1);
  KinematicsWorkspace<double> a(m), b(m);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd q = m.default_coordinates();
    for (int c = 0; c < m.num_coordinates(); ++c) q[c] += angle(rng);
    scaled_forward_kinematics(m, q.data(), f.data(), a);
    forward_kinematics(scaled, q.data(), b);
    for (std::size_t k = 0; k < m.bodies.size(); ++k) {
      EXPECT_LT((a.body_in_ground[k].translation_m - b.body_in_ground[k].translation_m).norm(), 1e-14) << m.bodies[k].name;
      EXPECT_LT((a.body_in_ground[k].rotation - b.body_in_ground[k].rotation).norm(), 1e-14) << m.bodies[k].name;
    }
  }
}

// A path spring scales as OpenSim's PathSpring::extendPostScale: its points with their bodies, its
// resting length by its path's length ratio at the default pose (exactly the factor when every body
// scales by the same factor).
TEST(ScaleModel, PathSpringsScaleTheirPointsAndRestingLength) {
  const std::string path = refdata::shared_path("opensim/gait10dof18musc/OutputReference/CMC/subject01_metabolics_path_spring.osim");
  REQUIRE_REFERENCE(path);
  const Model m = read_osim(path).model;
  ASSERT_EQ(m.path_springs.size(), 1u);
  const Model s = scale_model(m, std::vector<Eigen::Vector3d>(m.bodies.size(), Eigen::Vector3d::Constant(1.1)), false, -1);
  ASSERT_EQ(s.path_springs.size(), 1u);
  EXPECT_NEAR(s.path_springs[0].resting_length_m, 1.1 * m.path_springs[0].resting_length_m, 1e-12);
  for (std::size_t k = 0; k < m.path_springs[0].path.size(); ++k)
    EXPECT_LT((s.path_springs[0].path[k].location_m - 1.1 * m.path_springs[0].path[k].location_m).norm(), 1e-15);
  // Uneven factors: the resting length follows the path's own length ratio.
  std::vector<Eigen::Vector3d> f(m.bodies.size(), Eigen::Vector3d::Ones());
  f[m.body_index("tibia_r")] = Eigen::Vector3d(1.0, 1.2, 1.0);
  const Model u = scale_model(m, f, false, -1);
  const Eigen::VectorXd q0 = m.default_coordinates();
  KinematicsWorkspace<double> wm(m), wu(u);
  forward_kinematics(m, q0.data(), wm);
  forward_kinematics(u, q0.data(), wu);
  const double ratio = path_length(u, u.path_springs[0], q0.data(), wu) / path_length(m, m.path_springs[0], q0.data(), wm);
  EXPECT_GT(ratio, 1.01);
  EXPECT_NEAR(u.path_springs[0].resting_length_m, ratio * m.path_springs[0].resting_length_m, 1e-12);
}
