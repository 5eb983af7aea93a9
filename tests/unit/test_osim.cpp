#include <gtest/gtest.h>

#include <pugixml.hpp>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/xml_document.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

TEST(Osim, ReadsTheFixtureModel) {
  const OsimReadResult r = read_osim(refdata::fixture("models/walker.osim"));
  const Model& m = r.model;
  EXPECT_EQ(m.bodies.size(), 9u);  // ground + 8
  EXPECT_EQ(m.num_coordinates(), 19);
  EXPECT_EQ(m.markers.size(), 29u);
  EXPECT_EQ(m.muscles.size(), 6u);
  EXPECT_NEAR(m.total_mass_kg(), 67.4, 1e-9);
  EXPECT_TRUE(m.coordinates[m.coordinate_index("lumbar_rotation")].locked);
  EXPECT_TRUE(m.coordinates[m.coordinate_index("knee_angle_r")].clamped);
  EXPECT_EQ(m.coordinates[m.coordinate_index("pelvis_ty")].motion, Coordinate::Motion::kTranslational);
  EXPECT_EQ(m.coordinates[m.coordinate_index("knee_angle_r")].motion, Coordinate::Motion::kCoupled);
  EXPECT_DOUBLE_EQ(m.coordinates[m.coordinate_index("pelvis_ty")].default_value, 0.95);
  // PinJoint converted to a rotation about Z of its offset frames.
  const Joint& ankle = m.joints[m.joint_index("ankle_r")];
  EXPECT_EQ(ankle.type, "PinJoint");
  EXPECT_EQ(ankle.axes[0].coordinate, m.coordinate_index("ankle_angle_r"));
  EXPECT_TRUE(ankle.axes[0].axis.isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(ankle.parent_offset.translation_m.y(), -0.43, 1e-12);
  // Joints are ordered parent before child.
  for (const Joint& j : m.joints) EXPECT_TRUE(j.parent_body == 0 || m.bodies[j.parent_body].joint < m.bodies[j.child_body].joint);
  // Path points of each kind.
  const Muscle& vas = m.muscles[0];
  EXPECT_EQ(vas.name, "vas_r");
  ASSERT_EQ(vas.path.size(), 3u);
  EXPECT_EQ(vas.path[1].kind, PathPoint::Kind::kConditional);
  EXPECT_EQ(vas.path[1].coordinate, m.coordinate_index("knee_angle_r"));
  EXPECT_DOUBLE_EQ(vas.path[1].range_max, -1.42);
  EXPECT_EQ(vas.path[2].kind, PathPoint::Kind::kMoving);
  EXPECT_EQ(vas.path[2].moving_coordinates[1], m.coordinate_index("knee_angle_r"));
  EXPECT_NEAR(vas.path[2].moving_functions[2].value(0.3), 0.0018, 1e-15);
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
}

TEST(Osim, ReadsOpenSim3Documents) {
  // OpenSim 3.x layout: joints inside child bodies, location_in_parent, CoordinateSet, <function>
  // wrappers, markers on <body>, inertia_xx...
  const char* doc = R"(<?xml version="1.0"?>
<OpenSimDocument Version="30000"><Model name="old">
 <gravity>0 -9.81 0</gravity>
 <BodySet><objects>
  <Body name="ground"><mass>0</mass></Body>
  <Body name="thigh">
   <mass>8</mass><mass_center>0 -0.2 0</mass_center>
   <inertia_xx>0.1</inertia_xx><inertia_yy>0.02</inertia_yy><inertia_zz>0.1</inertia_zz>
   <inertia_xy>0</inertia_xy><inertia_xz>0</inertia_xz><inertia_yz>0.001</inertia_yz>
   <joint><CustomJoint name="hip">
    <parent_body>ground</parent_body>
    <location_in_parent>0 1 0</location_in_parent><orientation_in_parent>0 0 0</orientation_in_parent>
    <location>0 0 0</location><orientation>0 0 0</orientation>
    <CoordinateSet><objects><Coordinate name="hip_flexion"><default_value>0</default_value><range>-1 2</range></Coordinate></objects></CoordinateSet>
    <SpatialTransform>
     <TransformAxis name="rotation1"><function><LinearFunction><coefficients>1 0</coefficients></LinearFunction></function><coordinates>hip_flexion</coordinates><axis>0 0 1</axis></TransformAxis>
     <TransformAxis name="translation2"><function><Constant><value>0.05</value></Constant></function><coordinates></coordinates><axis>0 1 0</axis></TransformAxis>
    </SpatialTransform>
   </CustomJoint></joint>
  </Body>
 </objects></BodySet>
 <MarkerSet><objects><Marker name="knee"><body>thigh</body><location>0 -0.4 0</location></Marker></objects></MarkerSet>
 <ForceSet><objects><PrescribedForce name="push"/></objects></ForceSet>
</Model></OpenSimDocument>)";
  const OsimReadResult r = parse_osim(doc, "old.osim");
  const Model& m = r.model;
  ASSERT_EQ(m.bodies.size(), 2u);
  EXPECT_DOUBLE_EQ(m.bodies[1].inertia_kg_m2(1, 2), 0.001);
  ASSERT_EQ(m.markers.size(), 1u);
  // Knee marker at hip_flexion = 90 deg: thigh rotated about z, hanging 0.4 m -> points +x.
  KinematicsWorkspace<double> ws(m);
  const double q = M_PI / 2;
  forward_kinematics(m, &q, ws);
  const Eigen::Vector3d p = marker_position(m, 0, ws);
  EXPECT_NEAR(p.x(), 0.4, 1e-12);
  EXPECT_NEAR(p.y(), 1.05, 1e-12);
  ASSERT_EQ(r.warnings.size(), 1u);  // the unsupported force is reported, not dropped
  EXPECT_NE(r.warnings[0].find("PrescribedForce"), std::string::npos);
}

// OpenSim 4 registers NaturalCubicSpline as another name of SimmSpline, so a knee translation given
// as one takes the SimmSpline's values (not a natural spline's, which differ between the knots).
TEST(Osim, NaturalCubicSplineIsReadAsOpenSimReadsIt) {
  const std::vector<double> x{-2.0944, -1.2217, -0.5236, -0.3491, -0.1745, 0.1591, 2.0944};
  const std::vector<double> y{-0.4226, -0.4082, -0.399, -0.3976, -0.3966, -0.3953, -0.396};
  auto cells = [](const std::vector<double>& v) {
    std::string s;
    for (double e : v) s += std::to_string(e) + " ";
    return s;
  };
  const std::string doc = R"(<OpenSimDocument Version="20302"><Model name="knee"><BodySet><objects>
  <Body name="ground"/>
  <Body name="tibia"><mass>3</mass><Joint><CustomJoint name="knee"><parent_body>ground</parent_body>
    <CoordinateSet><objects><Coordinate name="knee_angle"><range>-2 0.1</range></Coordinate></objects></CoordinateSet>
    <SpatialTransform>
     <TransformAxis name="rotation1"><coordinates>knee_angle</coordinates><axis>0 0 1</axis></TransformAxis>
     <TransformAxis name="translation2"><function><NaturalCubicSpline><x>)" +
                          cells(x) + "</x><y>" + cells(y) + R"(</y></NaturalCubicSpline></function>
       <coordinates>knee_angle</coordinates><axis>0 1 0</axis></TransformAxis>
    </SpatialTransform></CustomJoint></Joint></Body>
 </objects></BodySet></Model></OpenSimDocument>)";
  const Model m = parse_osim(doc, "knee.osim").model;
  const Function simm = Function::simm_spline(x, y);
  const TransformAxis& ty = m.joints[0].axes[4];
  ASSERT_EQ(ty.coordinate, 0);
  for (double q = -2.0; q <= 0.1; q += 0.05) EXPECT_NEAR(ty.function.value(q), simm.value(q), 1e-15) << q;
}

TEST(Osim, MalformedInputNamesLineAndElement) {
  try {
    parse_osim("<OpenSimDocument>\n<Model name='x'>\n<BodySet>\n</Model>", "broken.osim");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "broken.osim");
    EXPECT_GE(e.line(), 3);
    EXPECT_NE(std::string(e.what()).find("malformed XML"), std::string::npos);
  }
  try {
    parse_osim("<OpenSimDocument><Model>\n<BodySet><objects>\n<Body name='a'><mass>heavy</mass></Body>\n</objects></BodySet></Model></OpenSimDocument>",
               "bad.osim");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.field(), "mass");
  }
  EXPECT_THROW(parse_osim("<html/>", "page.osim"), InputError);
  // A body with no joint cannot be placed.
  EXPECT_THROW(parse_osim("<Model><BodySet><objects><Body name='a'><mass>1</mass></Body></objects></BodySet></Model>", "x"),
               InputError);
}

TEST(OsimReference, ReadsGait2392) {
  const std::string path = refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(path);
  const OsimReadResult r = read_osim(path);
  const Model& m = r.model;
  EXPECT_EQ(m.bodies.size(), 13u);
  EXPECT_EQ(m.num_coordinates(), 23);
  EXPECT_EQ(m.muscles.size(), 92u);
  EXPECT_EQ(m.markers.size(), 39u);
  EXPECT_NEAR(m.total_mass_kg(), 72.6, 0.05);
  int conditional = 0, moving = 0;
  for (const auto& mu : m.muscles) {
    EXPECT_EQ(mu.type, "Thelen2003Muscle");
    for (const auto& p : mu.path) {
      conditional += p.kind == PathPoint::Kind::kConditional;
      moving += p.kind == PathPoint::Kind::kMoving;
    }
  }
  EXPECT_EQ(conditional, 26);
  EXPECT_EQ(moving, 8);
  const int vas = [&] { for (int i = 0; i < 92; ++i) if (m.muscles[i].name == "vas_int_r") return i; return -1; }();
  ASSERT_GE(vas, 0);
  EXPECT_DOUBLE_EQ(m.muscles[vas].max_isometric_force_N, 1365);
  EXPECT_DOUBLE_EQ(m.muscles[vas].activation_time_constant_s, 0.01);
  for (const auto& w : r.warnings) ADD_FAILURE() << "unexpected warning: " << w;
}

TEST(OsimReference, ReadsGenericModelAndMarkerSetFile) {
  const std::string model = refdata::gait2392("model/gait2392_simbody.osim");
  const std::string markers = refdata::gait2392("pipeline/gait2392_Scale_MarkerSet.xml");
  REQUIRE_REFERENCE(model);
  REQUIRE_REFERENCE(markers);
  OsimReadOptions o;
  o.marker_set_file = markers;
  const OsimReadResult r = read_osim(model, o);
  EXPECT_EQ(r.model.num_coordinates(), 23);
  EXPECT_EQ(r.model.markers.size(), 39u);  // the marker set's 39; the generic model has none
  EXPECT_GE(r.model.marker_index("R.ASIS"), 0);
}

TEST(OsimReference, ReadsMillardMuscles) {
  const std::string path = refdata::gait2392("model/gait2392_millard2012muscle.osim");
  REQUIRE_REFERENCE(path);
  const OsimReadResult r = read_osim(path);
  ASSERT_EQ(r.model.muscles.size(), 92u);
  // Every muscle's parameters as the file states them (read here with pugixml, independently).
  pugi::xml_document doc;
  ASSERT_TRUE(doc.load_file(path.c_str()));
  int compared = 0;
  for (const auto& x : doc.select_nodes("//Millard2012EquilibriumMuscle")) {
    const pugi::xml_node e = x.node();
    const auto it = std::find_if(r.model.muscles.begin(), r.model.muscles.end(),
                                 [&](const Muscle& m) { return m.name == e.attribute("name").value(); });
    ASSERT_NE(it, r.model.muscles.end()) << e.attribute("name").value();
    const Muscle& mu = *it;
    EXPECT_EQ(mu.type, "Millard2012EquilibriumMuscle");
    EXPECT_DOUBLE_EQ(mu.max_isometric_force_N, e.child("max_isometric_force").text().as_double()) << mu.name;
    EXPECT_DOUBLE_EQ(mu.optimal_fiber_length_m, e.child("optimal_fiber_length").text().as_double()) << mu.name;
    EXPECT_DOUBLE_EQ(mu.tendon_slack_length_m, e.child("tendon_slack_length").text().as_double()) << mu.name;
    EXPECT_DOUBLE_EQ(mu.pennation_angle_at_optimal_rad, e.child("pennation_angle_at_optimal").text().as_double()) << mu.name;
    EXPECT_DOUBLE_EQ(mu.max_contraction_velocity, e.child("max_contraction_velocity").text().as_double()) << mu.name;
    if (e.child("activation_time_constant")) {
      EXPECT_DOUBLE_EQ(mu.activation_time_constant_s, e.child("activation_time_constant").text().as_double()) << mu.name;
    }
    ++compared;
  }
  EXPECT_EQ(compared, 92);
}

// Setups as OpenSim's own files spell them: a comment before the tool, and the IK tests'
// "InverseKinemtaticsTool".
TEST(SetupDocuments, ToolFoundUnderOpenSimsOwnSpellings) {
  const auto d = xml::Document::load_string(
      "<OpenSimDocument Version=\"20302\">\n<!-- made by hand -->\n<InverseKinemtaticsTool name=\"subject01\">"
      "<model_file>m.osim</model_file></InverseKinemtaticsTool></OpenSimDocument>",
      "ik.xml");
  const auto tool = d.tool("InverseKinematicsTool");
  EXPECT_EQ(d.text(tool, "model_file"), "m.osim");
  EXPECT_THROW(d.tool("InverseDynamicsTool"), InputError);
  // OpenSim writes "Unassigned" for a property not set: read as absent.
  const auto u = xml::Document::load_string("<IKTool><marker_file>Unassigned</marker_file><x> a </x></IKTool>", "u.xml");
  EXPECT_EQ(u.text(u.doc().document_element(), "marker_file", "none"), "none");
  EXPECT_EQ(u.text(u.doc().document_element(), "x"), "a");
}
