// Wrapping surfaces: the cylinder's geodesic and the ellipsoid's chords against hand-computed cases,
// OpenSim's quadrant rule,
// moment arms against -dL/dq on arm26 (four wrap cylinders), and the models OpenSim's own tests use.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <random>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/muscles/muscle_path.h"
#include "cpgait/muscles/wrap_cylinder.h"
#include "cpgait/muscles/wrap_ellipsoid.h"
#include "cpgait/muscles/wrap_sphere.h"
#include "cpgait/muscles/wrap_torus.h"
#include "test_support.h"

namespace cpgait {
namespace {

WrapObject cylinder(double radius, double length, int quadrant_axis = -1, int quadrant_sign = 0) {
  WrapObject c;
  c.radius_m = radius;
  c.length_m = length;
  c.quadrant_axis = quadrant_axis;
  c.quadrant_sign = quadrant_sign;
  return c;
}

// A line passing below the axis (y = -h) from x = -x0 to x = +x0, rising from z1 to z2: unrolled, the
// path is one straight line of horizontal extent 2 d + R phi, d = sqrt(rho^2 - R^2) each side and
// phi = pi - 2 atan(h / x0) - 2 acos(R / rho) the arc under the axis.
TEST(WrapCylinder, AStraightLineOverACylinderHasTheGeodesicsLength) {
  const double R = 0.02, x0 = 0.1, h = 0.005, z1 = -0.01, z2 = 0.03;
  const Eigen::Vector3d p1(-x0, -h, z1), p2(x0, -h, z2);
  const SegmentWrap<double> w = wrap_cylinder(cylinder(R, 1.0), p1, p2);
  ASSERT_EQ(w.status, WrapStatus::kMandatoryWrap);
  const double rho = std::hypot(x0, h), d = std::sqrt(rho * rho - R * R);
  const double phi = M_PI - 2 * std::atan(h / x0) - 2 * std::acos(R / rho);
  const double expected = std::hypot(2 * d + R * phi, z2 - z1);
  const double got = (w.r1 - p1).norm() + w.surface_length_m + (p2 - w.r2).norm();
  EXPECT_NEAR(got, expected, 1e-14);
  // Tangent points on the surface, under the axis, rising at the path's one slope.
  EXPECT_NEAR(w.r1.head<2>().norm(), R, 1e-15);
  EXPECT_NEAR(w.r2.head<2>().norm(), R, 1e-15);
  EXPECT_LT(w.r1.y(), 0);
  EXPECT_LT(w.r2.y(), 0);
  const double slope = (z2 - z1) / (2 * d + R * phi);
  EXPECT_NEAR((w.r1.z() - z1) / d, slope, 1e-13);
  EXPECT_NEAR((w.r2.z() - w.r1.z()) / (R * phi), slope, 1e-13);
  // The straight parts are tangent: perpendicular to the radius at their tangent point.
  EXPECT_NEAR((w.r1 - p1).head<2>().dot(w.r1.head<2>()), 0, 1e-15);
  EXPECT_NEAR((p2 - w.r2).head<2>().dot(w.r2.head<2>()), 0, 1e-15);
}

TEST(WrapCylinder, WrapsOnlyWhereOpenSimDoes) {
  const WrapObject free_cylinder = cylinder(0.02, 0.1);
  // A segment that misses the cylinder, one with an end inside it, and one whose tangent points lie
  // beyond the cylinder's ends.
  EXPECT_EQ(wrap_cylinder(free_cylinder, Eigen::Vector3d(-0.1, 0.03, 0), Eigen::Vector3d(0.1, 0.03, 0)).status,
            WrapStatus::kNoWrap);
  EXPECT_EQ(wrap_cylinder(free_cylinder, Eigen::Vector3d(-0.1, 0.0, 0), Eigen::Vector3d(0.01, 0.0, 0)).status,
            WrapStatus::kInsideRadius);
  EXPECT_EQ(wrap_cylinder(free_cylinder, Eigen::Vector3d(-0.1, 0.001, 0.2), Eigen::Vector3d(0.1, 0.001, 0.3)).status,
            WrapStatus::kNoWrap);
  // Constrained to +y: a segment on the +y side that misses does not wrap; one that passes the axis
  // on the -y side without touching, from +y to -y, wraps over the +y side all the same.
  const WrapObject plus_y = cylinder(0.02, 0.1, 1, +1);
  EXPECT_EQ(wrap_cylinder(plus_y, Eigen::Vector3d(-0.1, 0.03, 0), Eigen::Vector3d(0.1, 0.03, 0)).status,
            WrapStatus::kNoWrap);
  const Eigen::Vector3d p1(-0.1, 0.01, 0), p2(0.1, -0.06, 0);
  const SegmentWrap<double> w = wrap_cylinder(plus_y, p1, p2);
  ASSERT_EQ(w.status, WrapStatus::kWrapped);
  EXPECT_GT(w.r1.y(), 0);
  EXPECT_GT(w.r2.y(), 0);
  EXPECT_EQ(wrap_cylinder(free_cylinder, p1, p2).status, WrapStatus::kNoWrap);
}

// An ellipsoid with equal semi-axes is a sphere: a segment passing under its centre, level, wraps in
// the plane through the centre, over the great circle, with OpenSim's length (1 mm chords).
TEST(WrapEllipsoid, ASphereWrapsOverItsGreatCircleInChords) {
  WrapObject sphere;
  sphere.shape = WrapObject::Shape::kEllipsoid;
  const double R = 0.02, x0 = 0.1, h = 0.005;
  sphere.dimensions_m = Eigen::Vector3d::Constant(R);
  const Eigen::Vector3d p1(-x0, -h, 0), p2(x0, -h, 0);
  for (auto method : {PathWrap::Method::kHybrid, PathWrap::Method::kMidpoint, PathWrap::Method::kAxial}) {
    const SegmentWrap<double> w = wrap_ellipsoid(sphere, method, p1, p2);
    ASSERT_EQ(w.status, WrapStatus::kMandatoryWrap);
    const double rho = std::hypot(x0, h), d = std::sqrt(rho * rho - R * R);
    const double phi = M_PI - 2 * std::atan(h / x0) - 2 * std::acos(R / rho);
    const int n = static_cast<int>(2 * R * std::sin(phi / 2) / 0.001);
    const double chords = n * 2 * R * std::sin(phi / (2 * n));
    // OpenSim stops its tangent-point search at a residual of 1e-4 in units of the semi-axes' mean
    // (2e-6 m here); the tangent points move along the surface within that, which changes the total
    // length only to second order (measured 7.6e-9 m).
    const double total = (w.r1 - p1).norm() + w.surface_length_m + (p2 - w.r2).norm();
    EXPECT_NEAR(total, 2 * d + chords, 2e-8);
    EXPECT_NEAR(w.r1.z(), 0, 1e-12);
    EXPECT_NEAR(w.r1.norm(), R, 2e-6);
    EXPECT_NEAR(w.r2.norm(), R, 2e-6);
    EXPECT_LT(std::abs((w.r1 - p1).normalized().dot(w.r1.normalized())), 1e-4);  // tangent
  }
  // A segment that passes beside the sphere, one that ends inside it.
  EXPECT_EQ(wrap_ellipsoid(sphere, PathWrap::Method::kHybrid, Eigen::Vector3d(-x0, -0.03, 0), Eigen::Vector3d(x0, -0.03, 0)).status,
            WrapStatus::kNoWrap);
  EXPECT_EQ(wrap_ellipsoid(sphere, PathWrap::Method::kHybrid, Eigen::Vector3d(-x0, 0, 0), Eigen::Vector3d(0.01, 0, 0)).status,
            WrapStatus::kInsideRadius);
}

// The sphere: the great circle in the plane of the ends and the centre, exactly.
TEST(WrapSphere, ASegmentUnderTheCentreWrapsOverTheGreatCircle) {
  WrapObject sphere;
  sphere.shape = WrapObject::Shape::kSphere;
  sphere.radius_m = 0.02;
  const double R = 0.02, x0 = 0.1, h = 0.005;
  // Tilted out of every coordinate plane: the great circle's plane is found, not assumed.
  const Eigen::Matrix3d tilt = rotation_from_body_xyz(Eigen::Vector3d(0.3, -0.2, 0.5));
  const Eigen::Vector3d p1 = tilt * Eigen::Vector3d(-x0, -h, 0), p2 = tilt * Eigen::Vector3d(x0, -h, 0);
  const SegmentWrap<double> w = wrap_sphere(sphere, p1, p2);
  ASSERT_EQ(w.status, WrapStatus::kWrapped);
  const double rho = std::hypot(x0, h), d = std::sqrt(rho * rho - R * R);
  const double phi = M_PI - 2 * std::atan(h / x0) - 2 * std::acos(R / rho);
  EXPECT_NEAR(w.surface_length_m, R * phi, 1e-15);
  EXPECT_NEAR((w.r1 - p1).norm(), d, 1e-15);
  EXPECT_NEAR((p2 - w.r2).norm(), d, 1e-15);
  EXPECT_NEAR(w.r1.norm(), R, 1e-15);
  EXPECT_NEAR((w.r1 - p1).dot(w.r1), 0, 1e-16);
  EXPECT_LT((tilt.transpose() * w.r1).y(), 0);  // under the centre, as the segment passes
  EXPECT_EQ(wrap_sphere(sphere, tilt * Eigen::Vector3d(-x0, -0.03, 0), tilt * Eigen::Vector3d(x0, -0.03, 0)).status,
            WrapStatus::kNoWrap);
  EXPECT_EQ(wrap_sphere(sphere, Eigen::Vector3d(-x0, 0, 0), Eigen::Vector3d(0.01, 0, 0)).status, WrapStatus::kInsideRadius);
}

// The torus (OpenSim's WrapTorus): a path threaded through the ring wraps its tube on the side facing
// the ring's centre. In the plane holding the torus's axis and the path, that is a circle of the inner
// radius about the centre circle's point: two tangents and an arc, exactly.
TEST(WrapTorus, APathThroughTheRingWrapsTheTubesInnerSide) {
  WrapObject torus;
  torus.shape = WrapObject::Shape::kTorus;
  torus.inner_radius_m = 0.01;
  torus.outer_radius_m = 0.05;
  const double r = 0.01, R = 0.05;
  for (double phi : {0.0, 0.7, 2.5, -1.9}) {  // the plane's angle about the torus's axis
    const Eigen::Matrix3d about_z = Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d centre = about_z * Eigen::Vector3d(R, 0, 0);
    // Above the tube, then below it and further in: the straight segment cuts the tube.
    const Eigen::Vector3d p1 = about_z * Eigen::Vector3d(R + 0.004, 0, 0.08), p2 = about_z * Eigen::Vector3d(R - 0.002, 0, -0.06);
    const SegmentWrap<double> w = wrap_torus(torus, p1, p2);
    ASSERT_TRUE(w.wraps()) << phi;
    // The planar answer: tangents from each point, and the arc between the tangent points going
    // round the inner side (towards the torus's axis).
    const Eigen::Vector2d a(0.004, 0.08), b(-0.002, -0.06);  // (radial offset from the centre circle, z)
    auto tangent_angle = [&](const Eigen::Vector2d& p, double sign) {
      return std::atan2(p.y(), p.x()) + sign * std::acos(r / p.norm());
    };
    // Going round through the inner side (angle pi): from above (angle ~pi/2) to below (~-pi/2 = 3pi/2).
    const double t1 = tangent_angle(a, +1), t2 = tangent_angle(b, -1) + 2 * M_PI;
    EXPECT_NEAR(w.surface_length_m, r * (t2 - t1), 1e-12) << phi;
    EXPECT_NEAR((w.r1 - p1).norm(), std::sqrt(a.squaredNorm() - r * r), 1e-12) << phi;
    EXPECT_NEAR((p2 - w.r2).norm(), std::sqrt(b.squaredNorm() - r * r), 1e-12) << phi;
    for (const Eigen::Vector3d& t : {w.r1, w.r2}) {
      EXPECT_NEAR((t - centre).norm(), r, 1e-12) << phi;                 // on the tube
      EXPECT_LT(t.head<2>().norm(), R) << phi;                           // on its inner side
      EXPECT_NEAR((about_z.transpose() * t).y(), 0, 1e-12) << phi;       // in the plane
    }
  }
  // Through the ring, clear of the tube: no wrap. Constrained to the other half: no wrap.
  EXPECT_FALSE(wrap_torus(torus, Eigen::Vector3d(0.03, 0, 0.08), Eigen::Vector3d(0.03, 0.001, -0.06)).wraps());
  torus.quadrant_axis = 0;
  torus.quadrant_sign = -1;
  EXPECT_FALSE(wrap_torus(torus, Eigen::Vector3d(R + 0.004, 0, 0.08), Eigen::Vector3d(R - 0.002, 0, -0.06)).wraps());
  torus.quadrant_sign = 1;
  EXPECT_TRUE(wrap_torus(torus, Eigen::Vector3d(R + 0.004, 0, 0.08), Eigen::Vector3d(R - 0.002, 0, -0.06)).wraps());
}

// A WrapTorus in a model: read with its radii (OpenSim's refusal of inner >= outer kept, naming the
// line), and a path that names it wraps over it.
TEST(WrapTorus, IsReadAndWrappedByThePathsThatNameIt) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/Analyze/arm26.osim");
  REQUIRE_REFERENCE(path);
  std::string doc = text::read_file(path);
  const std::size_t objects = doc.find("<objects>", doc.rfind("<WrapObjectSet", doc.find("<WrapCylinder name=\"TRI\">")));
  ASSERT_NE(objects, std::string::npos);
  doc.insert(objects + 9, "<WrapTorus name=\"ring\"><translation>0 0 0</translation><inner_radius>0.005</inner_radius>"
                          "<outer_radius>0.02</outer_radius></WrapTorus>");
  const std::size_t tri = doc.find("<wrap_object>TRI</wrap_object>");
  ASSERT_NE(tri, std::string::npos);
  doc.replace(tri, 30, "<wrap_object>ring</wrap_object>");
  const OsimReadResult r = parse_osim(doc, "arm26_torus.osim");
  for (const auto& w : r.warnings) EXPECT_EQ(w.find("WrapTorus"), std::string::npos) << w;
  const int ring = r.model.wrap_object_index("ring");
  ASSERT_GE(ring, 0);
  EXPECT_EQ(r.model.wrap_objects[ring].inner_radius_m, 0.005);
  EXPECT_EQ(r.model.wrap_objects[ring].outer_radius_m, 0.02);
  int named = 0;
  for (const Muscle& mu : r.model.muscles)
    for (const PathWrap& pw : mu.wraps) named += pw.wrap_object == ring;
  EXPECT_EQ(named, 1);
  std::string bad = doc;
  bad.replace(bad.find("<outer_radius>0.02"), 18, "<outer_radius>0.004");
  try {
    parse_osim(bad, "arm26_torus.osim");
    ADD_FAILURE() << "accepted a torus whose tube is wider than its ring";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inner_radius < outer_radius"), std::string::npos) << e.what();
    EXPECT_GT(e.line(), 0);
  }
}

// arm26: three triceps heads and the brachialis over the elbow's cylinder, the long head also over
// the glenoid's (constrained to +x).
std::string arm26() { return refdata::shared_path("opensim/opensim-core-tests/Analyze/arm26.osim"); }

bool wraps_now(const Model& m, int muscle, const Eigen::VectorXd& q) {
  KinematicsWorkspace<double> ws(m);
  forward_kinematics(m, q.data(), ws);
  std::vector<PathVertex<double>> path;
  current_path(m, m.muscles[muscle], q.data(), ws, path);
  return path.size() > m.muscles[muscle].path.size();
}

// Largest |analytic moment arm - (-dL/dq by central differences)| over the muscles and coordinates.
// Muscles over an ellipsoid are left out: OpenSim's ellipsoid path (a plane chosen by heuristics, its
// length summed over a whole number of 1 mm chords) jumps as that number changes, so only its
// moment arm as OpenSim defines it (the segments' pull) can be compared (MuscleAnalysisArm26).
bool over_an_ellipsoid(const Model& m, const Muscle& mu) {
  for (const auto& w : mu.wraps)
    if (m.wrap_objects[w.wrap_object].shape == WrapObject::Shape::kEllipsoid) return true;
  return false;
}

double moment_arm_error(const Model& m, const Eigen::VectorXd& q, int only_muscle = -1) {
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  MusclePathGeometry g(m);
  const Eigen::VectorXd qd = Eigen::VectorXd::Zero(m.num_coordinates());
  forward_kinematics(m, q.data(), ws);
  motion_subspace(m, q.data(), ws, S);
  muscle_path_geometry(m, q.data(), qd.data(), ws, S, g);
  double worst = 0;
  const double h = 1e-6;
  for (int c = 0; c < m.num_coordinates(); ++c) {
    Eigen::VectorXd qp = q, qm = q;
    qp[c] += h;
    qm[c] -= h;
    for (std::size_t k = 0; k < m.muscles.size(); ++k) {
      if (over_an_ellipsoid(m, m.muscles[k]) || (only_muscle >= 0 && static_cast<int>(k) != only_muscle)) continue;
      forward_kinematics(m, qp.data(), ws);
      const double lp = path_length(m, m.muscles[k], qp.data(), ws);
      forward_kinematics(m, qm.data(), ws);
      const double lm = path_length(m, m.muscles[k], qm.data(), ws);
      worst = std::max(worst, std::abs(g.moment_arm_m(k, c) + (lp - lm) / (2 * h)));
    }
  }
  return worst;
}

TEST(WrapCylinder, Arm26MomentArmsEqualMinusTheLengthsDerivative) {
  REQUIRE_REFERENCE(arm26());
  const OsimReadResult r = read_osim(arm26());
  const Model& m = r.model;
  int wrapping = 0;
  for (const auto& mu : m.muscles) wrapping += mu.wraps.empty() ? 0 : 1;
  ASSERT_EQ(wrapping, 5);  // the triceps heads and brachialis over cylinders, the biceps' long head over an ellipsoid
  std::mt19937 rng(7);
  int wrapped_poses = 0;
  double worst = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::VectorXd q = refdata::random_pose(m, rng);
    wrapped_poses += wraps_now(m, m.muscles.size() - 1, q) ? 1 : 0;
    worst = std::max(worst, moment_arm_error(m, q));
  }
  std::printf("arm26, 100 random poses (brachialis wrapped in %d): max |r + dL/dq| %.2e m\n", wrapped_poses, worst);
  // The same with the humeral head's ellipsoids made spheres (a geodesic again): the biceps' long head
  // wraps over one. (The triceps' long head then wraps over three surfaces at once, where OpenSim's
  // passes stop within 0.5 mm of a settled length, so its path is no geodesic: 5.9e-4 m measured.)
  Model spheres = m;
  for (auto& o : spheres.wrap_objects)
    if (o.shape == WrapObject::Shape::kEllipsoid) o.shape = WrapObject::Shape::kSphere, o.radius_m = o.dimensions_m.minCoeff();
  const int biclong = spheres.muscles[3].name == "BIClong" ? 3 : -1;
  ASSERT_EQ(biclong, 3);
  int sphere_wraps = 0;
  double worst_sphere = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::VectorXd q = refdata::random_pose(spheres, rng);
    sphere_wraps += wraps_now(spheres, biclong, q) ? 1 : 0;
    worst_sphere = std::max(worst_sphere, moment_arm_error(spheres, q, biclong));
  }
  std::printf("arm26 with spheres, 100 poses (long biceps wrapped in %d): max |r + dL/dq| %.2e m\n", sphere_wraps, worst_sphere);
  EXPECT_GT(sphere_wraps, 5);
  EXPECT_LT(worst_sphere, 1e-6);
  EXPECT_GT(wrapped_poses, 10);
  EXPECT_LT(wrapped_poses, 90);
  EXPECT_LT(worst, 1e-6);
  // Where the brachialis' path just meets the elbow's cylinder: bisect the elbow angle to 1e-9 rad and
  // check either side. Its length is continuous there and so is its moment arm.
  Eigen::VectorXd q = m.default_coordinates();
  const int elbow = m.coordinate_index("r_elbow_flex"), bra = static_cast<int>(m.muscles.size()) - 1;
  ASSERT_EQ(m.muscles[bra].name, "BRA");
  double lo = 0.0, hi = 2.2;
  q[elbow] = lo;
  const bool wraps_lo = wraps_now(m, bra, q);
  q[elbow] = hi;
  ASSERT_NE(wraps_lo, wraps_now(m, bra, q)) << "the brachialis should meet its cylinder between 0 and 2.2 rad";
  while (hi - lo > 1e-9) {
    q[elbow] = 0.5 * (lo + hi);
    (wraps_now(m, bra, q) == wraps_lo ? lo : hi) = q[elbow];
  }
  std::printf("brachialis meets the cylinder at elbow %.6f rad\n", lo);
  for (double dq : {-1e-4, -1e-5, 1e-5, 1e-4}) {
    q[elbow] = lo + dq;
    EXPECT_LT(moment_arm_error(m, q), 1e-6) << "elbow " << q[elbow];
  }
}

// The segments' pass (what an integrator's stages use) gives each path's length bit for bit as
// current_path_length sums it, and its lengthening speed as dL/dq qd (muscle_path_geometry), on arm26
// (wrapping) and gait2392 (moving and conditional points); no stretching segment lies on one body.
TEST(MusclePath, SegmentsGiveTheLengthBitForBitAndTheSpeedOfTheMomentArms) {
  const std::string gait2392 = refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(arm26());
  REQUIRE_REFERENCE(gait2392);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  int paths = 0, wrapped = 0, moving = 0, skipped = 0;
  double worst_speed = 0;
  for (const std::string& file : {arm26(), gait2392}) {
    const Model m = read_osim(file).model;
    const int nq = m.num_coordinates();
    KinematicsWorkspace<double> ws(m);
    MotionSubspace S(m), S_speeds(m);
    MusclePathGeometry g(m);
    std::vector<Eigen::Matrix<double, 6, 1>> V(m.bodies.size());
    Eigen::Matrix<double, 6, Eigen::Dynamic> S_rate(6, nq);
    std::vector<PathVertex<double>> path;
    std::vector<StretchingSegment> segments;
    for (int trial = 0; trial < 50; ++trial) {
      const Eigen::VectorXd q = refdata::random_pose(m, rng);
      const Eigen::VectorXd qd = Eigen::VectorXd::NullaryExpr(nq, [&] { return noise(rng); });
      forward_kinematics(m, q.data(), ws);
      motion_subspace(m, q.data(), ws, S);
      motion_subspace_and_rate(m, q.data(), qd.data(), ws, S_speeds, V, S_rate);
      muscle_path_geometry(m, q.data(), qd.data(), ws, S, g);
      for (std::size_t k = 0; k < m.muscles.size(); ++k) {
        current_path(m, m.muscles[k], q.data(), ws, path);
        const double length = current_path_segments(path, segments);
        EXPECT_EQ(length, current_path_length(path)) << m.muscles[k].name;
        EXPECT_NEAR(length, g.length_m[k], 1e-12) << m.muscles[k].name;
        const double speed = current_path_lengthening_speed(path, segments, q.data(), qd.data(), ws, V);
        const double expected = g.lengthening_speed_m_s[k];
        worst_speed = std::max(worst_speed, std::abs(speed - expected) / (1.0 + std::abs(expected)));
        for (const StretchingSegment& s : segments) {
          const PathVertex<double>& u = path[s.u];
          const PathVertex<double>& v = path[s.v];
          const bool own = (u.point && u.point->kind == PathPoint::Kind::kMoving) || (v.point && v.point->kind == PathPoint::Kind::kMoving);
          EXPECT_TRUE(u.body != v.body || own) << m.muscles[k].name;
          EXPECT_EQ(s.d, v.x_ground - u.x_ground);
          EXPECT_EQ(s.n, s.d.norm());
          moving += own;
        }
        ++paths;
        wrapped += path.size() > m.muscles[k].path.size();
        skipped += static_cast<int>(path.size()) - 1 - static_cast<int>(segments.size());
      }
    }
  }
  std::printf("[info] %d paths (%d wrapped), %d segments skipped (on one body, over a surface), %d with a moving point: worst |speed - dL/dq qd| / (1 + |v|) %.1e\n",
              paths, wrapped, skipped, moving, worst_speed);
  EXPECT_LT(worst_speed, 1e-12);
  EXPECT_GT(wrapped, 0);
  EXPECT_GT(moving, 0);
  EXPECT_GT(skipped, 0);
}

// Every model OpenSim's own tests and examples ship loads, in every document version, and nothing
// among the components this issue calls for is reported unsupported.
TEST(OsimReader, EveryReferenceModelLoads) {
  const std::string root = refdata::shared_path("opensim");
  REQUIRE_REFERENCE(root);
  int models = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
    if (e.path().extension() != ".osim") continue;
    ++models;
    OsimReadResult r;
    ASSERT_NO_THROW(r = read_osim(e.path().string())) << e.path();
    EXPECT_GT(r.model.bodies.size(), 1u) << e.path();
    for (const auto& w : r.warnings) {
      EXPECT_EQ(w.find("WrapCylinder"), std::string::npos) << w;
      EXPECT_EQ(w.find("WrapEllipsoid"), std::string::npos) << w;
      EXPECT_EQ(w.find("no joint"), std::string::npos) << w;
      EXPECT_EQ(w.find("Thelen2003Muscle"), std::string::npos) << w;
      EXPECT_EQ(w.find("Millard2012EquilibriumMuscle"), std::string::npos) << w;
      // Read and computed now: no "not supported" for them.
      for (const char* type : {"Schutte1993Muscle", "RigidTendonMuscle", "CoordinateLimitForce", "CoordinateCouplerConstraint"})
        if (w.find(type) != std::string::npos) {
          EXPECT_EQ(w.find("not supported"), std::string::npos) << w;
        }
    }
  }
  std::printf("%d models read\n", models);
  EXPECT_GE(models, 30);
}

// The 1.x document (TransformAxisSet joints, muscles holding their own MusclePointSet) reads as the
// same mechanism: its joint axes and the knee's coupled translations as OpenSim converts them.
TEST(OsimReader, A1xDocumentReadsItsTransformAxesAndMusclePoints) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/Analyze/subject01_simbody.osim");
  REQUIRE_REFERENCE(path);
  const Model m = read_osim(path).model;
  EXPECT_EQ(m.muscles.size(), 54u);
  EXPECT_EQ(m.num_coordinates(), 23);
  const Joint& knee = m.joints[m.joint_index("knee_r")];
  ASSERT_GE(knee.axes[0].coordinate, 0);
  EXPECT_EQ(m.coordinates[knee.axes[0].coordinate].name, "knee_angle_r");
  // Its first translation follows the spline the file gives (x = -2.0944 -> y = -0.0032).
  EXPECT_EQ(m.coordinates[knee.axes[3].coordinate].name, "knee_angle_r");
  EXPECT_NEAR(knee.axes[3].function.value(-2.09439510), -0.0032, 1e-12);
  EXPECT_NEAR(knee.axes[4].function.value(-2.09439510), -0.4226, 1e-12);
  const Joint& pelvis = m.joints[m.joint_index("ground_pelvis")];
  EXPECT_EQ(m.coordinates[pelvis.axes[0].coordinate].name, "pelvis_tilt");
  EXPECT_TRUE(pelvis.axes[0].axis.isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_EQ(m.coordinates[pelvis.axes[5].coordinate].name, "pelvis_tz");
  for (const auto& mu : m.muscles) EXPECT_GE(mu.path.size(), 2u) << mu.name;
  EXPECT_NEAR(m.muscles[0].optimal_fiber_length_m, 0.0535, 1e-12);
  EXPECT_NEAR(m.muscles[0].pennation_angle_at_optimal_rad, 0.13962634, 1e-12);
}

}  // namespace
}  // namespace cpgait
