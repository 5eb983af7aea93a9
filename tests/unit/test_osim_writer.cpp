// The .osim writer: a scaled model written into its source document reads back as the same model,
// for every document version under ../shared, and the document keeps everything else it held.
#include <gtest/gtest.h>

#include <pugixml.hpp>

#include <filesystem>
#include <map>
#include <random>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/model/osim_writer.h"
#include "cpgait/scaling/scale_model.h"
#include "test_support.h"

using namespace cpgait;

namespace {

// The largest difference between two models with the same structure, over everything scaling
// changes (m or kg or kg m^2, relative for inertias); functions compared over [-2, 2].
double largest_difference(const Model& a, const Model& b) {
  double d = 0;
  auto at = [&](double x) { d = std::max(d, std::abs(x)); };
  EXPECT_EQ(a.bodies.size(), b.bodies.size());
  for (std::size_t i = 0; i < a.bodies.size() && i < b.bodies.size(); ++i) {
    at(a.bodies[i].mass_kg - b.bodies[i].mass_kg);
    at((a.bodies[i].com_m - b.bodies[i].com_m).norm());
    at((a.bodies[i].inertia_kg_m2 - b.bodies[i].inertia_kg_m2).norm() / (1e-12 + b.bodies[i].inertia_kg_m2.norm()));
  }
  EXPECT_EQ(a.joints.size(), b.joints.size());
  for (std::size_t i = 0; i < a.joints.size() && i < b.joints.size(); ++i) {
    at((a.joints[i].parent_offset.translation_m - b.joints[i].parent_offset.translation_m).norm());
    at((a.joints[i].child_offset.translation_m - b.joints[i].child_offset.translation_m).norm());
    for (int k = 0; k < 6; ++k)
      for (double q = -2; q <= 2; q += 0.25) at(a.joints[i].axes[k].function.value(q) - b.joints[i].axes[k].function.value(q));
  }
  EXPECT_EQ(a.markers.size(), b.markers.size());
  for (std::size_t i = 0; i < a.markers.size() && i < b.markers.size(); ++i) {
    EXPECT_EQ(a.markers[i].name, b.markers[i].name);
    EXPECT_EQ(a.markers[i].body, b.markers[i].body);
    EXPECT_EQ(a.markers[i].fixed, b.markers[i].fixed);
    at((a.markers[i].location_m - b.markers[i].location_m).norm());
  }
  EXPECT_EQ(a.wrap_objects.size(), b.wrap_objects.size());
  for (std::size_t i = 0; i < a.wrap_objects.size() && i < b.wrap_objects.size(); ++i) {
    const WrapObject &x = a.wrap_objects[i], &y = b.wrap_objects[i];
    at((x.pose.translation_m - y.pose.translation_m).norm());
    at(x.radius_m - y.radius_m);
    at(x.length_m - y.length_m);
    at((x.dimensions_m - y.dimensions_m).norm());
  }
  EXPECT_EQ(a.muscles.size(), b.muscles.size());
  for (std::size_t i = 0; i < a.muscles.size() && i < b.muscles.size(); ++i) {
    const Muscle &x = a.muscles[i], &y = b.muscles[i];
    at(x.optimal_fiber_length_m - y.optimal_fiber_length_m);
    at(x.tendon_slack_length_m - y.tendon_slack_length_m);
    EXPECT_EQ(x.path.size(), y.path.size()) << x.name;
    for (std::size_t k = 0; k < x.path.size() && k < y.path.size(); ++k) {
      at((x.path[k].location_m - y.path[k].location_m).norm());
      for (int c = 0; c < 3; ++c)
        for (double q = -2; q <= 2; q += 0.25) at(x.path[k].moving_functions[c].value(q) - y.path[k].moving_functions[c].value(q));
    }
  }
  EXPECT_EQ(a.path_springs.size(), b.path_springs.size());
  for (std::size_t i = 0; i < a.path_springs.size() && i < b.path_springs.size(); ++i) {
    const PathSpring &x = a.path_springs[i], &y = b.path_springs[i];
    at(x.resting_length_m - y.resting_length_m);
    EXPECT_EQ(x.path.size(), y.path.size()) << x.name;
    for (std::size_t k = 0; k < x.path.size() && k < y.path.size(); ++k) at((x.path[k].location_m - y.path[k].location_m).norm());
  }
  EXPECT_EQ(a.path_actuators.size(), b.path_actuators.size());
  for (std::size_t i = 0; i < a.path_actuators.size() && i < b.path_actuators.size(); ++i) {
    const PathActuator &x = a.path_actuators[i], &y = b.path_actuators[i];
    EXPECT_EQ(x.path.size(), y.path.size()) << x.name;
    for (std::size_t k = 0; k < x.path.size() && k < y.path.size(); ++k) at((x.path[k].location_m - y.path[k].location_m).norm());
  }
  return d;
}

// Per body and axis, factors between 0.8 and 1.25, different on every axis (so that the inertia's
// cylinder rule and the wrap objects' per-axis rules are exercised).
std::vector<Eigen::Vector3d> uneven_factors(const Model& m, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.8, 1.25);
  std::vector<Eigen::Vector3d> f(m.bodies.size());
  for (auto& v : f) v = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return f;
}

std::map<std::string, int> element_counts(const std::string& text) {
  pugi::xml_document d;
  EXPECT_TRUE(d.load_string(text.c_str()));
  std::map<std::string, int> counts;
  struct Walker : pugi::xml_tree_walker {
    std::map<std::string, int>* counts;
    bool for_each(pugi::xml_node& n) override {
      if (n.type() == pugi::node_element) ++(*counts)[n.name()];
      return true;
    }
  } w;
  w.counts = &counts;
  d.traverse(w);
  return counts;
}

}  // namespace

// Every model under ../shared/reference/opensim (1.x to 4.x documents), scaled unevenly with a mass,
// written and read back, is the scaled model (to the printed digits), and the document holds the same
// elements as before but for the MultiplierFunctions scaling adds (and their <function> wrappers).
TEST(OsimWriter, EveryReferenceModelScaledReadsBackAsScaled) {
  const std::string root = refdata::shared_path("opensim");
  REQUIRE_REFERENCE(root);
  int models = 0;
  double worst = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
    if (e.path().extension() != ".osim") continue;
    const std::string path = e.path().string();
    const Model generic = read_osim(path).model;
    const Model scaled = scale_model(generic, uneven_factors(generic, 7 + models), false, 80.0);
    std::string written;
    ASSERT_NO_THROW(written = osim_document(scaled, {"scaled", ""})) << path;
    const Model back = parse_osim(written, path + " (written)").model;
    EXPECT_EQ(back.name, "scaled");
    const double d = largest_difference(back, scaled);
    EXPECT_LT(d, 1e-14) << path;
    worst = std::max(worst, d);
    // The same elements, plus the MultiplierFunctions and their <function>s.
    auto before = element_counts(text::read_file(path)), after = element_counts(written);
    const int added = after["MultiplierFunction"] - before["MultiplierFunction"];
    EXPECT_GE(added, 0) << path;
    after["MultiplierFunction"] -= added;
    after["function"] -= added;
    after["scale"] -= added;
    for (auto& [name, n] : after)
      if (n == 0) before.try_emplace(name, 0);
    for (const auto& [name, n] : before) EXPECT_EQ(after[name], n) << path << ": <" << name << ">";
    ++models;
  }
  std::printf("%d models scaled, written and read back; largest difference %.1e\n", models, worst);
  EXPECT_GE(models, 30);
}

// A 3.x document: inertias in inertia_xx.., joints at location_in_parent, a constant translation
// wrapped in <function>: scaled in the document's own layout.
TEST(OsimWriter, Writes3xDocumentsInTheirOwnLayout) {
  const std::string doc = R"(<?xml version="1.0"?>
<OpenSimDocument Version="30000"><Model name="old">
 <BodySet><objects>
  <Body name="ground"><mass>0</mass></Body>
  <Body name="thigh">
   <mass>8</mass><mass_center>0 -0.2 0</mass_center>
   <inertia_xx>0.1</inertia_xx><inertia_yy>0.02</inertia_yy><inertia_zz>0.1</inertia_zz>
   <inertia_xy>0</inertia_xy><inertia_xz>0</inertia_xz><inertia_yz>0</inertia_yz>
   <Joint><CustomJoint name="hip">
    <parent_body>ground</parent_body>
    <location_in_parent>0 1 0</location_in_parent><orientation_in_parent>0 0 0</orientation_in_parent>
    <location>0 0.1 0</location><orientation>0 0 0</orientation>
    <CoordinateSet><objects><Coordinate name="hip_flexion"><range>-1 2</range></Coordinate></objects></CoordinateSet>
    <SpatialTransform>
     <TransformAxis name="rotation1"><function><LinearFunction><coefficients>1 0</coefficients></LinearFunction></function><coordinates>hip_flexion</coordinates><axis>0 0 1</axis></TransformAxis>
     <TransformAxis name="translation2"><function><Constant><value>0.05</value></Constant></function><coordinates></coordinates><axis>0 1 0</axis></TransformAxis>
    </SpatialTransform>
   </CustomJoint></Joint>
  </Body>
 </objects></BodySet>
 <MarkerSet><objects><Marker name="knee"><body>thigh</body><location>0 -0.4 0</location><fixed>false</fixed></Marker></objects></MarkerSet>
</Model></OpenSimDocument>)";
  const Model generic = parse_osim(doc, "old.osim").model;
  std::vector<Eigen::Vector3d> f(2, Eigen::Vector3d(1, 1, 1));
  f[0] = Eigen::Vector3d(2, 2, 2);   // ground's factors scale the hip's location in ground
  f[1] = Eigen::Vector3d(1, 1.5, 1);  // the thigh: longer
  const Model scaled = scale_model(generic, f, true, -1);
  OsimWriteOptions o;
  o.source_document = doc;
  const std::string written = osim_document(scaled, o);
  pugi::xml_document d;
  ASSERT_TRUE(d.load_string(written.c_str()));
  const pugi::xml_node thigh = d.child("OpenSimDocument").child("Model").child("BodySet").child("objects").find_child_by_attribute("Body", "name", "thigh");
  EXPECT_STREQ(thigh.child("mass_center").text().get(), "0 -0.30000000000000004 0");
  EXPECT_FALSE(thigh.child("inertia"));  // 3.x layout kept
  // Stretched along y, the cylinder's moments across it grow; about its axis they stay.
  EXPECT_NE(std::string(thigh.child("inertia_xx").text().get()), "0.1");
  EXPECT_STREQ(thigh.child("inertia_yy").text().get(), "0.02");
  const pugi::xml_node hip = thigh.child("Joint").child("CustomJoint");
  EXPECT_STREQ(hip.child("location_in_parent").text().get(), "0 2 0");
  EXPECT_STREQ(hip.child("location").text().get(), "0 0.15000000000000002 0");
  // The constant translation along y: the parent's (ground's) y factor 2, in a MultiplierFunction
  // inside the 3.x <function> wrapper.
  const pugi::xml_node mf = hip.child("SpatialTransform").find_child_by_attribute("TransformAxis", "name", "translation2")
                                .child("function").child("MultiplierFunction");
  ASSERT_TRUE(mf);
  EXPECT_STREQ(mf.child("scale").text().get(), "2");
  EXPECT_TRUE(mf.child("function").child("Constant"));
  // The marker set is written in 3.x form (<body>), its location scaled.
  const pugi::xml_node knee = d.child("OpenSimDocument").child("Model").child("MarkerSet").child("objects").child("Marker");
  EXPECT_STREQ(knee.child("body").text().get(), "thigh");
  EXPECT_STREQ(knee.child("location").text().get(), "0 -0.60000000000000009 0");
  const Model back = parse_osim(written, "old.osim (written)").model;
  EXPECT_LT(largest_difference(back, scaled), 1e-15);
  EXPECT_NEAR(back.joints[0].axes[4].function.value(0.3), 0.1, 1e-15);
}

// A model not read from a document has nothing to be written into.
TEST(OsimWriter, AModelWithoutADocumentIsRefused) {
  Model m;
  EXPECT_THROW(osim_document(m), InputError);
}
