#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <random>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

namespace {


// The analytic Jacobian of every marker (motion subspace) against forward-mode autodiff through the
// templated forward kinematics.
void check_jacobians(const Model& m, int poses) {
  std::mt19937 rng(7);
  constexpr int N = 32;
  ASSERT_LE(m.num_coordinates(), N);
  using Jet = ceres::Jet<double, N>;
  KinematicsWorkspace<double> ws(m);
  KinematicsWorkspace<Jet> wj(m);
  MotionSubspace S(m);
  for (int trial = 0; trial < poses; ++trial) {
    const Eigen::VectorXd q = refdata::random_pose(m, rng, 3.0);
    std::vector<Jet> qj(m.num_coordinates());
    for (int c = 0; c < m.num_coordinates(); ++c) qj[c] = Jet(q[c], c);
    forward_kinematics(m, q.data(), ws);
    forward_kinematics(m, qj.data(), wj);
    motion_subspace(m, q.data(), ws, S);
    for (int k = 0; k < static_cast<int>(m.markers.size()); ++k) {
      const Eigen::Vector3d p = marker_position(m, k, ws);
      const auto pj = marker_position(m, k, wj);
      const std::vector<int> anc = ancestor_coordinates(m, m.markers[k].body);
      for (int c = 0; c < m.num_coordinates(); ++c) {
        const bool moves = std::find(anc.begin(), anc.end(), c) != anc.end();
        const Eigen::Vector3d analytic =
            moves ? Eigen::Vector3d(S.columns.col(c).head<3>().cross(p) + S.columns.col(c).tail<3>()) : Eigen::Vector3d::Zero();
        for (int a = 0; a < 3; ++a) {
          EXPECT_NEAR(pj[a].a, p[a], 1e-14);
          EXPECT_NEAR(analytic[a], pj[a].v[c], 1e-10) << m.markers[k].name << " d/d" << m.coordinates[c].name;
        }
      }
    }
  }
}

}  // namespace

TEST(Kinematics, JacobianMatchesAutodiffOnFixtureModel) {
  check_jacobians(read_osim(refdata::fixture("models/walker.osim")).model, 20);
}

TEST(Kinematics, JacobianMatchesFiniteDifferences) {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  std::mt19937 rng(3);
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  const int toe = m.marker_index("R.Toe");
  for (int t = 0; t < 10; ++t) {
    Eigen::VectorXd q = refdata::random_pose(m, rng, 3.0);
    forward_kinematics(m, q.data(), ws);
    motion_subspace(m, q.data(), ws, S);
    const Eigen::Vector3d p = marker_position(m, toe, ws);
    for (int c = 0; c < m.num_coordinates(); ++c) {
      const double h = 1e-6;
      Eigen::VectorXd qp = q, qm = q;
      qp[c] += h;
      qm[c] -= h;
      forward_kinematics(m, qp.data(), ws);
      const Eigen::Vector3d pp = marker_position(m, toe, ws);
      forward_kinematics(m, qm.data(), ws);
      const Eigen::Vector3d fd = (pp - marker_position(m, toe, ws)) / (2 * h);
      const auto anc = ancestor_coordinates(m, m.markers[toe].body);
      const bool moves = std::find(anc.begin(), anc.end(), c) != anc.end();
      const Eigen::Vector3d analytic = moves ? Eigen::Vector3d(S.columns.col(c).head<3>().cross(p) + S.columns.col(c).tail<3>()) : Eigen::Vector3d::Zero();
      EXPECT_LT((analytic - fd).norm(), 1e-7) << m.coordinates[c].name;
    }
  }
}

TEST(KinematicsReference, JacobianMatchesAutodiffOnGait2392) {
  const std::string path = refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(path);
  check_jacobians(read_osim(path).model, 5);
}

// OpenSim 4.1, run here on the same files, wrote both its pose per frame and its marker errors at
// that pose. Our forward kinematics at OpenSim's pose must reproduce those errors: this checks joint
// conventions, offset frames and the knee's spline-coupled translations to micrometres (a wrong
// rotation order or spline end condition moves markers by millimetres).
TEST(KinematicsReference, ReproducesOpenSimMarkerErrorsAtOpenSimsPoses) {
  const std::string model_path = refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  const std::string trc_path = refdata::gait2392("pipeline/subject01_walk1.trc");
  const std::string setup_path = refdata::gait2392("pipeline/subject01_Setup_IK.xml");
  const std::string pose_path = refdata::shared_path("opensim41-here/IK/subject01_walk1_ik.mot");
  const std::string err_path = refdata::shared_path("opensim41-here/IK/subject01_ik_marker_errors.sto");
  for (const auto& p : {model_path, trc_path, setup_path, pose_path, err_path}) REQUIRE_REFERENCE(p);
  const Model m = read_osim(model_path).model;
  const MarkerTrial trial = read_trc(trc_path);
  const Storage pose = read_storage(pose_path), errors = read_storage(err_path);
  const IkTargets targets = make_ik_targets(m, trial, read_ik_setup(setup_path).tasks, {});
  ASSERT_EQ(targets.markers.size(), 31u);  // OpenSim's RMS is over the 31 weighted markers
  KinematicsWorkspace<double> ws(m);
  double worst_rms = 0, worst_max = 0;
  for (int r = 0; r < pose.num_rows(); ++r) {
    int frame = -1;
    for (int f = 0; f < trial.num_frames(); ++f)
      if (std::abs(trial.time_s[f] - pose.time()[r]) < 1e-6) frame = f;
    ASSERT_GE(frame, 0);
    Eigen::VectorXd q(m.num_coordinates());
    for (int c = 0; c < m.num_coordinates(); ++c)
      q[c] = pose.data(r, refdata::required_column(pose, m.coordinates[c].name)) * (m.coordinates[c].is_angle() ? M_PI / 180 : 1.0);
    forward_kinematics(m, q.data(), ws);
    double sum2 = 0, mx = 0;
    for (const auto& t : targets.markers) {
      const double e = (marker_position(m, t.model_marker, ws) - trial.position_m(frame, t.trial_marker)).norm();
      sum2 += e * e;
      mx = std::max(mx, e);
    }
    const double rms = std::sqrt(sum2 / targets.markers.size());
    worst_rms = std::max(worst_rms, std::abs(rms - errors.data(r, refdata::required_column(errors, "marker_error_RMS"))));
    worst_max = std::max(worst_max, std::abs(mx - errors.data(r, refdata::required_column(errors, "marker_error_max"))));
  }
  // The files print 8 decimals (1e-8 m, 1e-8 deg): agreement to 1 micrometre is exact in effect.
  EXPECT_LT(worst_rms, 1e-6);
  EXPECT_LT(worst_max, 1e-6);
  std::printf("[ info ] at OpenSim 4.1's poses: marker RMS within %.2e m, max error within %.2e m of OpenSim's\n",
              worst_rms, worst_max);
}

// Every joint type the reader converts to a spatial transform, chained, with offset frames: the
// converted axes must give the documented motions, and the Jacobian must match autodiff.
TEST(Kinematics, AllJointTypesMoveAsOpenSimDefinesThem) {
  const char* doc = R"(<OpenSimDocument Version="40000"><Model name="joints">
  <Ground name="ground"/>
  <BodySet><objects>
   <Body name="a"><mass>1</mass><mass_center>0 0 0</mass_center><inertia>1 1 1 0 0 0</inertia></Body>
   <Body name="b"><mass>1</mass></Body><Body name="c"><mass>1</mass></Body><Body name="d"><mass>1</mass></Body>
   <Body name="e"><mass>1</mass></Body><Body name="f"><mass>1</mass></Body>
  </objects></BodySet>
  <JointSet><objects>
   <FreeJoint name="free"><socket_parent_frame>/ground</socket_parent_frame><socket_child_frame>/bodyset/a</socket_child_frame>
    <coordinates><Coordinate name="fx"/><Coordinate name="fy"/><Coordinate name="fz"/><Coordinate name="ftx"/><Coordinate name="fty"/><Coordinate name="ftz"/></coordinates></FreeJoint>
   <BallJoint name="ball"><socket_parent_frame>a_off</socket_parent_frame><socket_child_frame>/bodyset/b</socket_child_frame>
    <coordinates><Coordinate name="bx"/><Coordinate name="by"/><Coordinate name="bz"/></coordinates>
    <frames><PhysicalOffsetFrame name="a_off"><socket_parent>/bodyset/a</socket_parent><translation>0 -0.3 0.1</translation><orientation>0.2 0 -0.1</orientation></PhysicalOffsetFrame></frames></BallJoint>
   <SliderJoint name="slider"><socket_parent_frame>/bodyset/b</socket_parent_frame><socket_child_frame>/bodyset/c</socket_child_frame>
    <coordinates><Coordinate name="s"/></coordinates></SliderJoint>
   <UniversalJoint name="universal"><socket_parent_frame>/bodyset/c</socket_parent_frame><socket_child_frame>/bodyset/d</socket_child_frame>
    <coordinates><Coordinate name="u1"/><Coordinate name="u2"/></coordinates></UniversalJoint>
   <PlanarJoint name="planar"><socket_parent_frame>/bodyset/d</socket_parent_frame><socket_child_frame>/bodyset/e</socket_child_frame>
    <coordinates><Coordinate name="pr"/><Coordinate name="px"/><Coordinate name="py"/></coordinates></PlanarJoint>
   <WeldJoint name="weld"><socket_parent_frame>e_off</socket_parent_frame><socket_child_frame>/bodyset/f</socket_child_frame>
    <frames><PhysicalOffsetFrame name="e_off"><socket_parent>/bodyset/e</socket_parent><translation>0.1 0 0</translation><orientation>0 0.3 0</orientation></PhysicalOffsetFrame></frames></WeldJoint>
  </objects></JointSet>
  <MarkerSet><objects>
   <Marker name="ma"><socket_parent_frame>/bodyset/a</socket_parent_frame><location>0.1 0.2 0.3</location></Marker>
   <Marker name="mb"><socket_parent_frame>/bodyset/b</socket_parent_frame><location>0 -0.2 0</location></Marker>
   <Marker name="mf"><socket_parent_frame>/bodyset/f</socket_parent_frame><location>0.05 0.1 -0.2</location></Marker>
  </objects></MarkerSet>
 </Model></OpenSimDocument>)";
  const OsimReadResult r = parse_osim(doc, "joints.osim");
  const Model& m = r.model;
  ASSERT_EQ(m.num_coordinates(), 15);
  KinematicsWorkspace<double> ws(m);
  // Free joint: body-fixed X-Y-Z rotations, translation in ground.
  Eigen::VectorXd q = Eigen::VectorXd::Zero(15);
  q << 0.3, -0.2, 0.5, 1.0, 2.0, 3.0, 0, 0, 0, 0, 0, 0, 0, 0, 0;
  forward_kinematics(m, q.data(), ws);
  const Eigen::Matrix3d R = rotation_from_body_xyz(Eigen::Vector3d(0.3, -0.2, 0.5));
  EXPECT_LT((marker_position(m, 0, ws) - (R * Eigen::Vector3d(0.1, 0.2, 0.3) + Eigen::Vector3d(1, 2, 3))).norm(), 1e-14);
  // The slider moves along its parent's X axis: body b's, which at zero coordinates is turned by
  // the ball joint's offset frame.
  q.setZero();
  q[9] = 0.25;  // s
  forward_kinematics(m, q.data(), ws);
  const Eigen::Vector3d f0 = marker_position(m, 2, ws);
  q[9] = 0.0;
  forward_kinematics(m, q.data(), ws);
  const Eigen::Vector3d along = rotation_from_body_xyz(Eigen::Vector3d(0.2, 0, -0.1)) * Eigen::Vector3d(0.25, 0, 0);
  EXPECT_LT((f0 - marker_position(m, 2, ws) - along).norm(), 1e-14);
  check_jacobians(m, 10);
}
