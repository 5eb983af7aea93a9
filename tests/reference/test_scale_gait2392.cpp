// OpenSim's Scale tool on gait2392's subject01 setup: the ModelScaler's per-body scale factors from
// the setup's measurements on the static trial, against the scale set OpenSim 4.1 applied here
// (../shared/reference/opensim41-here/Scale/subject01_scaleSet_applied.xml, printed to 6 digits).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <fstream>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/scale_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/capture/xml_document.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/scaling/fit_scale_factors.h"
#include "cpgait/scaling/model_scale_factors.h"
#include "cpgait/scaling/place_markers.h"
#include "cpgait/scaling/scale_model.h"
#include "test_support.h"

namespace cpgait {
namespace {

// The setup, the generic model with the setup's marker set, and the static trial, as the tool loads
// them; empty (with the test skipped) when ../shared lacks a file.
struct Subject01Scale {
  std::string pipeline = refdata::shared_path("opensim/gait2392/pipeline/");
  std::string generic = refdata::shared_path("opensim/gait2392/model/gait2392_simbody.osim");
  ScaleSetup setup;
  Model model;
  MarkerTrial trial;
  std::string missing;  // the first file ../shared lacks
  bool load(std::initializer_list<std::string> also_needed) {
    for (const auto& f : {pipeline + "subject01_Setup_Scale.xml", pipeline + "gait2392_Scale_MarkerSet.xml",
                          pipeline + "subject01_static.trc", generic})
      if (!std::filesystem::exists(f)) return missing = f, false;
    for (const auto& f : also_needed)
      if (!std::filesystem::exists(f)) return missing = f, false;
    setup = read_scale_setup(pipeline + "subject01_Setup_Scale.xml");
    OsimReadOptions o;
    o.marker_set_file = pipeline + setup.marker_set_file;
    model = read_osim(generic, o).model;
    trial = read_trc(pipeline + setup.marker_file);
    return true;
  }
};

// The issue's acceptance 1 between a scaled model and OpenSim's: masses within 0.01 kg, centres of
// mass, joint offsets (and the knee's coupled translations) and path points within 0.5 mm, inertias
// within 0.5 %, markers within 1 mm, muscle lengths within 1e-6 (relative).
void expect_scaled_like(const Model& ours, const Model& theirs, const char* what) {
  double mass = 0, com = 0, inertia = 0, joint = 0, marker = 0, point = 0;
  for (const auto& b : theirs.bodies) {
    const int i = ours.body_index(b.name);
    ASSERT_GE(i, 0) << b.name;
    mass = std::max(mass, std::abs(ours.bodies[i].mass_kg - b.mass_kg));
    com = std::max(com, (ours.bodies[i].com_m - b.com_m).norm());
    if (b.inertia_kg_m2.norm() > 0)
      inertia = std::max(inertia, (ours.bodies[i].inertia_kg_m2 - b.inertia_kg_m2).norm() / b.inertia_kg_m2.norm());
  }
  for (const auto& j : theirs.joints) {
    const int i = ours.joint_index(j.name);
    ASSERT_GE(i, 0) << j.name;
    joint = std::max({joint, (ours.joints[i].parent_offset.translation_m - j.parent_offset.translation_m).norm(),
                      (ours.joints[i].child_offset.translation_m - j.child_offset.translation_m).norm()});
    // The knee's coupled translations: the functions' values over the knee's range.
    for (int k = 3; k < 6; ++k)
      for (double q = -2.0; q <= 0.1; q += 0.1)
        joint = std::max(joint, std::abs(ours.joints[i].axes[k].function.value(q) - j.axes[k].function.value(q)));
  }
  for (const auto& mk : theirs.markers) {
    const int i = ours.marker_index(mk.name);
    if (i < 0) continue;
    marker = std::max(marker, (ours.markers[i].location_m - mk.location_m).norm());
  }
  double muscle_length = 0;  // relative, optimal fibre and tendon slack lengths
  for (const auto& mu : theirs.muscles) {
    const int i = ours.muscle_index(mu.name);
    ASSERT_GE(i, 0) << mu.name;
    muscle_length = std::max({muscle_length,
                              std::abs(ours.muscles[i].optimal_fiber_length_m / mu.optimal_fiber_length_m - 1),
                              std::abs(ours.muscles[i].tendon_slack_length_m / mu.tendon_slack_length_m - 1)});
    ASSERT_EQ(ours.muscles[i].path.size(), mu.path.size()) << mu.name;
    for (std::size_t p = 0; p < mu.path.size(); ++p)
      point = std::max(point, (ours.muscles[i].path[p].location_m - mu.path[p].location_m).norm());
  }
  std::printf("%s: masses %.1e kg, centres of mass %.1e m, inertias %.1e (relative), joint offsets %.1e m, markers %.1e m, "
              "path points %.1e m, muscle lengths %.1e (relative)\n", what, mass, com, inertia, joint, marker, point, muscle_length);
  EXPECT_LT(muscle_length, 1e-6);
  EXPECT_LT(mass, 0.01);
  EXPECT_LT(com, 5e-4);
  EXPECT_LT(inertia, 5e-3);
  EXPECT_LT(joint, 5e-4);
  EXPECT_LT(marker, 1e-3);
  EXPECT_LT(point, 5e-4);
}

TEST(ScaleGait2392, MeasurementScaleFactorsMatchOpenSim41) {
  const std::string applied = refdata::shared_path("opensim41-here/Scale/subject01_scaleSet_applied.xml");
  Subject01Scale s;
  if (!s.load({applied})) GTEST_SKIP() << "reference data absent: " << s.missing;
  const ScaleSetup& setup = s.setup;
  const Model& model = s.model;
  const MarkerTrial& trial = s.trial;
  EXPECT_EQ(setup.model_file, "gait2392_simbody.osim");
  EXPECT_DOUBLE_EQ(setup.mass_kg, 72.6);
  ASSERT_EQ(setup.scaling_order.size(), 2u);
  EXPECT_TRUE(setup.preserve_mass_distribution);
  const ModelScaleFactors f = model_scale_factors(model, setup, &trial);
  // The setup scales the patellae, which gait2392_simbody does not have (OpenSim ignores them too).
  for (const auto& w : f.warnings) EXPECT_NE(w.find("patella"), std::string::npos) << w;

  // OpenSim's applied scale set, body by body.
  const auto d = xml::Document::load_file(applied);
  int compared = 0;
  double worst = 0;
  for (const auto& sc : d.doc().document_element().child("ScaleSet").child("objects").children("Scale")) {
    const std::string body = d.text(sc, "segment");
    const auto v = d.numbers(sc, "scales");
    const int b = model.body_index(body);
    if (b < 0) continue;  // OpenSim lists every frame; the model's bodies are what we scale
    for (int k = 0; k < 3; ++k) {
      const double rel = std::abs(f.body[b][k] - v[k]) / v[k];
      worst = std::max(worst, rel);
      EXPECT_LT(rel, 5e-6) << body << " axis " << k << ": ours " << f.body[b][k] << ", OpenSim's " << v[k];
    }
    ++compared;
  }
  std::printf("%d bodies' scale factors, largest relative difference from OpenSim 4.1's %.1e (it prints 6 digits)\n", compared,
              worst);
  EXPECT_EQ(compared, static_cast<int>(model.bodies.size()));
}

// The generic gait2392 scaled with those factors and the subject's 72.6 kg against the model OpenSim
// 4.1 wrote before placing markers (subject01_scaledOnly.osim): the issue's tolerances.
TEST(ScaleGait2392, ScaledModelMatchesOpenSim41) {
  const std::string theirs_path = refdata::shared_path("opensim41-here/Scale/subject01_scaledOnly.osim");
  Subject01Scale s;
  if (!s.load({theirs_path})) GTEST_SKIP() << "reference data absent: " << s.missing;
  const ScaleSetup& setup = s.setup;
  const Model& model = s.model;
  const MarkerTrial& trial = s.trial;
  const ModelScaleFactors f = model_scale_factors(model, setup, &trial);
  const Model ours = scale_model(model, f.body, setup.preserve_mass_distribution, setup.mass_kg);
  const Model theirs = read_osim(theirs_path).model;
  EXPECT_NEAR(ours.total_mass_kg(), 72.6, 1e-9);

  expect_scaled_like(ours, theirs, "scaled gait2392 vs OpenSim 4.1");
}

// The MarkerPlacer on the scaled model: the static pose and the placed markers against OpenSim 4.1's
// (subject01_simbody.osim and subject01_static_output.mot in opensim41-here/Scale).
TEST(ScaleGait2392, PlacedMarkersMatchOpenSim41) {
  const std::string placed_path = refdata::shared_path("opensim41-here/Scale/subject01_simbody.osim");
  const std::string pose_path = refdata::shared_path("opensim41-here/Scale/subject01_static_output.mot");
  Subject01Scale s;
  if (!s.load({placed_path, pose_path})) GTEST_SKIP() << "reference data absent: " << s.missing;
  const std::string& pipeline = s.pipeline;
  const ScaleSetup& setup = s.setup;
  const Model& model = s.model;
  const MarkerTrial& trial = s.trial;
  ASSERT_TRUE(setup.placer_apply);
  EXPECT_FALSE(setup.placer_tasks.markers.empty());
  const Model scaled = scale_model(model, model_scale_factors(model, setup, &trial).body, setup.preserve_mass_distribution,
                                   setup.mass_kg);
  const MarkerTrial placer_trial = read_trc(pipeline + setup.placer_marker_file);
  const MarkerPlacement p = place_markers(scaled, placer_trial, setup.placer_tasks, setup.placer_time_range_s);
  const Model theirs = read_osim(placed_path).model;

  // The static pose: every coordinate OpenSim wrote (degrees for rotations).
  const Storage pose = read_storage(pose_path);
  double worst_angle_deg = 0;
  for (int c = 0; c < scaled.num_coordinates(); ++c) {
    int col = -1;
    for (int k = 1; k < pose.num_columns(); ++k)
      if (pose.labels[k].size() > scaled.coordinates[c].name.size() + 7 &&
          pose.labels[k].find("/" + scaled.coordinates[c].name + "/value") != std::string::npos)
        col = k;
    if (col < 0) continue;
    const double theirs_value = pose.data(0, col);  // inDegrees=no
    if (scaled.coordinates[c].is_angle()) {
      const double d = std::abs(p.static_pose[c] - theirs_value) * 180 / M_PI;
      if (d > 0.5) std::printf("  %s: ours %.3f deg, OpenSim's %.3f deg\n", scaled.coordinates[c].name.c_str(), p.static_pose[c] * 180 / M_PI, theirs_value * 180 / M_PI);
      worst_angle_deg = std::max(worst_angle_deg, d);
    }
  }
  double worst_marker = 0, sum2 = 0, worst_below_lumbar = 0;
  std::string worst_name;
  int n = 0;
  const int torso = scaled.body_index("torso");
  for (const auto& mk : theirs.markers) {
    const int i = p.model.marker_index(mk.name);
    if (i < 0) continue;
    const double d = (p.model.markers[i].location_m - mk.location_m).norm();
    sum2 += d * d;
    ++n;
    if (d > worst_marker) worst_marker = d, worst_name = mk.name;
    if (mk.body != torso) worst_below_lumbar = std::max(worst_below_lumbar, d);
  }
  std::printf("marker placement: %d markers moved, static pose within %.3f deg of OpenSim 4.1's, markers RMS %.2f mm, worst "
              "%.2f mm (%s), worst off the torso %.3f mm\n", p.markers_moved, worst_angle_deg, 1e3 * std::sqrt(sum2 / n),
              1e3 * worst_marker, worst_name.c_str(), 1e3 * worst_below_lumbar);
  // The static frame's weighted squared marker error on the scaled model at both poses: ours is the
  // IK optimum; OpenSim 4.1 stops with lumbar_bending 0.6 deg short of it (its IK accuracy 1e-5),
  // which moves Top.Head 10 mm. Measured: ours lower.
  {
    Eigen::VectorXd q_theirs = p.static_pose;
    for (int c = 0; c < scaled.num_coordinates(); ++c)
      for (int k = 1; k < pose.num_columns(); ++k)
        if (pose.labels[k].find("/" + scaled.coordinates[c].name + "/value") != std::string::npos) q_theirs[c] = pose.data(0, k);
    auto objective = [&](const Eigen::VectorXd& q) {
      KinematicsWorkspace<double> ws(scaled);
      forward_kinematics(scaled, q.data(), ws);
      double sum = 0;
      for (const auto& task : setup.placer_tasks.markers) {
        const int mi = scaled.marker_index(task.name), ti = placer_trial.marker_index(task.name);
        if (!task.apply || mi < 0 || ti < 0) continue;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        int frames = 0;
        for (int f = 0; f < placer_trial.num_frames(); ++f) {
          const double t = placer_trial.time_s[f];
          if (setup.placer_time_range_s && (t < setup.placer_time_range_s->first - 1e-9 || t > setup.placer_time_range_s->second + 1e-9)) continue;
          if (!placer_trial.position_m(f, ti).allFinite()) continue;
          mean += placer_trial.position_m(f, ti);
          ++frames;
        }
        sum += task.weight * (marker_position(scaled, mi, ws) - mean / frames).squaredNorm();
      }
      return sum;
    };
    const double ours_obj = objective(p.static_pose), theirs_obj = objective(q_theirs);
    std::printf("static-pose IK objective: ours %.6e, at OpenSim 4.1's pose %.6e\n", ours_obj, theirs_obj);
    EXPECT_LE(ours_obj, theirs_obj);
  }
  // Against the model shipped with the pipeline (placed by an older OpenSim).
  const std::string shipped_path = pipeline + "OutputReference/subject01_simbody.osim";
  if (std::filesystem::exists(shipped_path)) {
    const Model shipped = read_osim(shipped_path).model;
    double w = 0, s2 = 0;
    std::string wn;
    int k = 0;
    for (const auto& mk : shipped.markers) {
      const int i = p.model.marker_index(mk.name);
      if (i < 0) continue;
      const double d = (p.model.markers[i].location_m - mk.location_m).norm();
      s2 += d * d;
      ++k;
      if (d > w) w = d, wn = mk.name;
    }
    std::printf("against the shipped subject01_simbody.osim: RMS %.2f mm, worst %.2f mm (%s)\n", 1e3 * std::sqrt(s2 / k), 1e3 * w,
                wn.c_str());
    EXPECT_LT(w, 1e-6);  // measured: identical
  }
  EXPECT_GT(p.markers_moved, 20);
  // The issue's 1 mm against OpenSim 4.1 holds off the torso; the torso's markers follow the lumbar
  // bending OpenSim 4.1 stopped short of (above).
  EXPECT_LT(worst_below_lumbar, 1e-3);
}

// `cpgait run-tool` on the setup (with the generic model, which the setup names beside itself):
// the files OpenSim's ScaleTool writes, read back, against OpenSim 4.1's; the placed model's markers
// against the shipped model's; the scale set and static pose against the in-memory tool's.
TEST(ScaleGait2392, RunToolWritesWhatOpenSimsScaleToolWrites) {
  const std::string theirs_scaled = refdata::shared_path("opensim41-here/Scale/subject01_scaledOnly.osim");
  const std::string shipped = refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  Subject01Scale s;
  if (!s.load({theirs_scaled, shipped})) GTEST_SKIP() << "reference data absent: " << s.missing;
  const std::string out = refdata::temp_dir("scale_tool");
  const auto run = refdata::run_cpgait("run-tool " + s.pipeline + "subject01_Setup_Scale.xml --model " + s.generic + " --results " + out);
  ASSERT_EQ(run.status, 0) << run.output;
  const Model scaled = read_osim(out + "/subject01_scaledOnly.osim").model;
  EXPECT_EQ(scaled.name, "subject01");
  expect_scaled_like(scaled, read_osim(theirs_scaled).model, "written scaled model vs OpenSim 4.1's");

  // The placed model: the same bodies, markers where the shipped model has them.
  const Model placed = read_osim(out + "/subject01_simbody.osim").model;
  const Model ship = read_osim(shipped).model;
  double worst = 0;
  int compared = 0;
  for (const auto& mk : ship.markers) {
    const int i = placed.marker_index(mk.name);
    ASSERT_GE(i, 0) << mk.name;
    EXPECT_EQ(placed.bodies[placed.markers[i].body].name, ship.bodies[mk.body].name) << mk.name;
    worst = std::max(worst, (placed.markers[i].location_m - mk.location_m).norm());
    ++compared;
  }
  std::printf("written placed model: %d markers, worst %.1e m from the shipped subject01_simbody.osim\n", compared, worst);
  EXPECT_EQ(compared, static_cast<int>(placed.markers.size()));
  EXPECT_LT(worst, 1e-6);

  // The scale set: each body's factors as the tool computed them.
  const ModelScaleFactors f = model_scale_factors(s.model, s.setup, &s.trial);
  const auto d = xml::Document::load_file(out + "/subject01_scaleSet_applied.xml");
  int bodies = 0;
  for (const auto& sc : d.doc().document_element().child("ScaleSet").child("objects").children("Scale")) {
    const int b = s.model.body_index(d.text(sc, "segment"));
    ASSERT_GE(b, 0);
    const auto v = d.numbers(sc, "scales");
    ASSERT_EQ(v.size(), 3u);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(v[k], f.body[b][k]);
    ++bodies;
  }
  EXPECT_EQ(bodies, static_cast<int>(s.model.bodies.size()));

  // The static pose: one row at the range's start, as OpenSim's, every coordinate in degrees or m.
  const Storage pose = read_storage(out + "/subject01_static_output.mot");
  ASSERT_EQ(pose.num_rows(), 1);
  EXPECT_DOUBLE_EQ(pose.time()[0], s.setup.placer_time_range_s->first);
  const MarkerPlacement p = place_markers(scale_model(s.model, f.body, s.setup.preserve_mass_distribution, s.setup.mass_kg),
                                          s.trial, s.setup.placer_tasks, s.setup.placer_time_range_s);
  for (int c = 0; c < s.model.num_coordinates(); ++c) {
    const double unit = s.model.coordinates[c].is_angle() ? 180 / M_PI : 1.0;
    EXPECT_NEAR(pose.data(0, refdata::required_column(pose, s.model.coordinates[c].name)), p.static_pose[c] * unit, 1e-9);
  }
  std::filesystem::remove_all(out);
}

// Bad input: a measurement's marker missing from the static trial, a trial in the wrong units (factors
// far outside 0.5-2), a mass that is not positive, a marker set naming an unknown body: errors naming
// the file, the line and the field.
TEST(ScaleGait2392, BadInputNamesTheSetupLineAndField) {
  Subject01Scale s;
  if (!s.load({})) GTEST_SKIP() << "reference data absent: " << s.missing;
  ScaleSetup setup = s.setup;
  const ScaleMeasurement& first = setup.measurements.front();
  MarkerTrial renamed = s.trial;
  for (auto& n : renamed.marker_names)
    if (n == first.marker_pairs.front().first) n = "not_this_one";
  try {
    model_scale_factors(s.model, setup, &renamed);
    ADD_FAILURE() << "a missing marker was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), setup.file);
    EXPECT_EQ(e.line(), first.line);
    EXPECT_NE(e.field().find(first.name), std::string::npos) << e.what();
    EXPECT_NE(e.message().find(first.marker_pairs.front().first), std::string::npos) << e.what();
  }
  MarkerTrial in_cm = s.trial;  // millimetres read as centimetres: every distance 10x
  in_cm.positions_m *= 10;
  try {
    model_scale_factors(s.model, setup, &in_cm);
    ADD_FAILURE() << "a scale factor of 10 was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), first.line);
    EXPECT_NE(e.message().find("outside 0.5-2.0"), std::string::npos) << e.what();
  }
  const std::string dir = refdata::temp_dir("scale_bad");
  std::string text = text::read_file(s.pipeline + "subject01_Setup_Scale.xml");
  const auto at = text.find("<mass>");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, text.find("</mass>") - at, "<mass>0");
  { std::ofstream(dir + "/setup.xml") << text; }
  try {
    read_scale_setup(dir + "/setup.xml");
    ADD_FAILURE() << "a zero mass was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "mass");
    EXPECT_GT(e.line(), 0);
  }
  // A marker set naming a body the generic model lacks.
  {
    std::ofstream(dir + "/markers.xml") << "<OpenSimDocument Version=\"40000\"><MarkerSet><objects>\n"
                                           "<Marker name=\"X\"><socket_parent_frame>/bodyset/femur_r</socket_parent_frame></Marker>\n"
                                           "<Marker name=\"Y\"><socket_parent_frame>/bodyset/humerus_r</socket_parent_frame></Marker>\n"
                                           "</objects></MarkerSet></OpenSimDocument>\n";
  }
  OsimReadOptions o;
  o.marker_set_file = dir + "/markers.xml";
  try {
    read_osim(s.generic, o);
    ADD_FAILURE() << "a marker on an unknown body was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), dir + "/markers.xml");
    EXPECT_EQ(e.line(), 3);
    EXPECT_NE(e.message().find("humerus_r"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// Acceptance 2: IK of the walking trial on our scaled and placed model against IK on OpenSim 4.1's
// (the same IK, so the difference is the models'): per-frame marker RMS within 0.5 mm.
TEST(ScaleGait2392, WalkingIkOnOurModelMatchesIkOnOpenSims) {
  const std::string theirs_path = refdata::shared_path("opensim41-here/Scale/subject01_simbody.osim");
  Subject01Scale s;
  if (!s.load({theirs_path, s.pipeline + "subject01_walk1.trc", s.pipeline + "subject01_Setup_IK.xml"}))
    GTEST_SKIP() << "reference data absent: " << s.missing;
  const ModelScaleFactors f = model_scale_factors(s.model, s.setup, &s.trial);
  const Model scaled = scale_model(s.model, f.body, s.setup.preserve_mass_distribution, s.setup.mass_kg);
  const Model ours = place_markers(scaled, s.trial, s.setup.placer_tasks, s.setup.placer_time_range_s).model;
  const Model theirs = read_osim(theirs_path).model;
  const MarkerTrial walk = read_trc(s.pipeline + "subject01_walk1.trc");
  const IkSetup ik = read_ik_setup(s.pipeline + "subject01_Setup_IK.xml");
  IkOptions o;
  o.time_range_s = ik.time_range_s;
  const IkResult a = inverse_kinematics(ours, walk, ik.tasks, o), b = inverse_kinematics(theirs, walk, ik.tasks, o);
  ASSERT_EQ(a.marker_rms_m.size(), b.marker_rms_m.size());
  double worst = 0, mean_a = 0, mean_b = 0;
  for (Eigen::Index i = 0; i < a.marker_rms_m.size(); ++i) {
    worst = std::max(worst, std::abs(a.marker_rms_m[i] - b.marker_rms_m[i]));
    mean_a += a.marker_rms_m[i] / static_cast<double>(a.marker_rms_m.size());
    mean_b += b.marker_rms_m[i] / static_cast<double>(b.marker_rms_m.size());
  }
  std::printf("walk1 IK, %zu frames: mean marker RMS %.2f mm on ours, %.2f mm on OpenSim 4.1's; per frame within %.3f mm\n",
              a.marker_rms_m.size(), 1e3 * mean_a, 1e3 * mean_b, 1e3 * worst);
  EXPECT_GT(a.marker_rms_m.size(), 100u);
  EXPECT_LT(worst, 5e-4);
}

// `cpgait scale` without a setup: automatic scaling writes the placed model (the subject's mass), its
// scale set and static pose; a mass that is not positive is refused naming the option.
TEST(ScaleGait2392, ScaleCommandScalesAutomaticallyWithoutASetup) {
  Subject01Scale s;
  if (!s.load({})) GTEST_SKIP() << "reference data absent: " << s.missing;
  const std::string out = refdata::temp_dir("scale_auto");
  const std::string common = "scale --model " + s.generic + " --marker-set " + s.pipeline + "gait2392_Scale_MarkerSet.xml --static " +
                             s.pipeline + "subject01_static.trc --time 1 2 --results " + out;
  const auto bad = refdata::run_cpgait(common + " --mass -3");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.output.find("--mass"), std::string::npos) << bad.output;
  EXPECT_FALSE(std::filesystem::exists(out + "/subject01_static_scaled.osim"));
  const auto run = refdata::run_cpgait(common + " --mass 72.6 --name subject01");
  ASSERT_EQ(run.status, 0) << run.output;
  const Model m = read_osim(out + "/subject01_scaled.osim").model;
  EXPECT_EQ(m.name, "subject01");
  EXPECT_NEAR(m.total_mass_kg(), 72.6, 1e-9);
  EXPECT_EQ(m.markers.size(), s.model.markers.size());
  EXPECT_EQ(read_storage(out + "/subject01_static_output.mot").num_rows(), 1);
  EXPECT_TRUE(std::filesystem::exists(out + "/subject01_scaleSet_applied.xml"));
  EXPECT_NE(run.output.find("scale fit:"), std::string::npos) << run.output;
  std::filesystem::remove_all(out);
}

// Acceptance 4: the whole pipeline from the generic model (cpgait run --generic-model --static
// --scale-setup) against the same pipeline on the pre-scaled model the reference tests use (the
// shipped subject01_simbody.osim): the two models agree to 3.3e-7 m (markers), so the results differ by
// what that moves - far inside the reference tests' tolerances (IK 0.01 deg, SO 0.02). Its job.json
// records the factors and reruns to the same scaled model and IK.
TEST(ScaleGait2392, PipelineFromTheGenericModelMatchesThePrescaledModelsRun) {
  Subject01Scale s;
  const std::string walk = s.pipeline + "subject01_walk1";
  if (!s.load({walk + ".trc", walk + "_grf.mot", walk + "_grf.xml", s.pipeline + "subject01_Setup_IK.xml",
               s.pipeline + "OutputReference/subject01_simbody.osim"}))
    GTEST_SKIP() << "reference data absent: " << s.missing;
  const std::string dir = refdata::temp_dir("scale_pipeline");
  std::ofstream(dir + "/options.json") << std::string(R"({"gait": )") + refdata::kResidualGaitOptions + "}";
  const std::string trial = " --markers " + walk + ".trc --grf " + walk + "_grf.mot --loads " + walk + "_grf.xml --ik-tasks " +
                            s.pipeline + "subject01_Setup_IK.xml --options " + dir + "/options.json";
  const auto scaled = refdata::run_cpgait("run --generic-model " + s.generic + " --marker-set " + s.pipeline +
                                          "gait2392_Scale_MarkerSet.xml --static " + s.pipeline + "subject01_static.trc --scale-setup " +
                                          s.pipeline + "subject01_Setup_Scale.xml" + trial + " -o " + dir + "/generic");
  ASSERT_EQ(scaled.status, 0) << scaled.output;
  const auto pre = refdata::run_cpgait("run --model " + s.pipeline + "OutputReference/subject01_simbody.osim --scale-muscles-from " +
                                       s.generic + trial + " -o " + dir + "/prescaled");
  ASSERT_EQ(pre.status, 0) << pre.output;
  auto file = [&](const std::string& run, const std::string& suffix) { return dir + "/" + run + "/subject01_walk1" + suffix; };
  // Per column: the largest difference (IK, degrees or m) or the RMS over time (ID, N m; SO activations).
  auto compare = [&](const std::string& suffix, bool rms, const std::string& skip_containing) {
    const Storage a = read_storage(file("generic", suffix)), b = read_storage(file("prescaled", suffix));
    EXPECT_EQ(a.labels, b.labels) << suffix;
    EXPECT_EQ(a.num_rows(), b.num_rows()) << suffix;
    double worst = 0;
    for (int c = 1; c < a.num_columns() && a.num_rows() == b.num_rows(); ++c) {
      if (!skip_containing.empty() && a.labels[c].find(skip_containing) != std::string::npos) continue;
      const Eigen::VectorXd d = a.data.col(c) - b.data.col(c);
      worst = std::max(worst, rms ? std::sqrt(d.squaredNorm() / static_cast<double>(d.size())) : d.cwiseAbs().maxCoeff());
    }
    return worst;
  };
  const double ik = compare("_ik.mot", false, ""), id = compare("_id.sto", true, "");
  const double so = compare("_StaticOptimization_activation.sto", true, "_re");  // muscles, not residuals or reserves
  const nlohmann::json gait_a = nlohmann::json::parse(text::read_file(file("generic", "_gait.json")));
  const nlohmann::json gait_b = nlohmann::json::parse(text::read_file(file("prescaled", "_gait.json")));
  std::printf("pipeline from the generic model vs on the pre-scaled model: IK %.1e deg, ID %.3f N m RMS, SO activations %.4f "
              "RMS; gait speed %.4f vs %.4f m/s\n", ik, id, so, gait_a["speed_m_s"].get<double>(), gait_b["speed_m_s"].get<double>());
  EXPECT_LT(ik, 1e-3);   // measured 8.3e-5
  EXPECT_LT(id, 0.1);    // measured 0.053 (pelvis_tilt)
  EXPECT_LT(so, 0.01);   // measured 0.0064 (ext_dig_l)
  EXPECT_TRUE(gait_a["fell_at_s"].is_null());
  EXPECT_NEAR(gait_a["speed_m_s"].get<double>(), gait_b["speed_m_s"].get<double>(), 0.02 * gait_b["speed_m_s"].get<double>());
  // job.json records the factors; rerun (IK only), it rebuilds the same scaled model and IK.
  nlohmann::json job = nlohmann::json::parse(text::read_file(dir + "/generic/job.json"));
  ASSERT_TRUE(job["scale"].contains("factors")) << job.dump();
  EXPECT_NEAR(job["scale"]["factors"]["pelvis"][0].get<double>(), 1.02458, 1e-5);
  job["stages"] = {"ik"};
  { std::ofstream(dir + "/job.json") << job.dump(2); }
  const auto rerun = refdata::run_cpgait("run --options " + dir + "/job.json -o " + dir + "/rerun");
  ASSERT_EQ(rerun.status, 0) << rerun.output;
  for (const char* suffix : {"_scaled.osim", "_ik.mot"})
    EXPECT_EQ(text::read_file(file("rerun", suffix)), text::read_file(file("generic", suffix))) << suffix;
  std::filesystem::remove_all(dir);
}

// Acceptance 3: automatic scaling (no measurement set) from the generic model and the static trial,
// with the setup's marker weights: walk1's IK marker RMS on it against that on OpenSim 4.1's model
// (measurement-scaled and placed by the setup).
TEST(ScaleGait2392, AutomaticScalingWalksNoWorseThanOpenSimsModel) {
  const std::string theirs_path = refdata::shared_path("opensim41-here/Scale/subject01_simbody.osim");
  Subject01Scale s;
  if (!s.load({theirs_path, s.pipeline + "subject01_walk1.trc", s.pipeline + "subject01_Setup_IK.xml"}))
    GTEST_SKIP() << "reference data absent: " << s.missing;
  ScaleFitOptions o;
  o.static_time_range_s = s.setup.placer_time_range_s;
  o.subject_mass_kg = s.setup.mass_kg;
  const ScaleFit fit = fit_scale_factors(s.model, s.trial, s.setup.placer_tasks, {}, o);
  std::printf("%s\n", fit.summary.BriefReport().c_str());
  const ModelScaleFactors measured = model_scale_factors(s.model, s.setup, &s.trial);
  for (std::size_t b = 1; b < s.model.bodies.size(); ++b)
    std::printf("  %-10s fitted %.4f %.4f %.4f, measured %.4f %.4f %.4f\n", s.model.bodies[b].name.c_str(), fit.factors[b][0],
                fit.factors[b][1], fit.factors[b][2], measured.body[b][0], measured.body[b][1], measured.body[b][2]);
  const Model theirs = read_osim(theirs_path).model;
  const MarkerTrial walk = read_trc(s.pipeline + "subject01_walk1.trc");
  const IkSetup ik = read_ik_setup(s.pipeline + "subject01_Setup_IK.xml");
  IkOptions io;
  io.time_range_s = ik.time_range_s;
  const IkResult a = inverse_kinematics(fit.model, walk, ik.tasks, io), b = inverse_kinematics(theirs, walk, ik.tasks, io);
  std::printf("walk1 IK mean marker RMS: %.2f mm on the automatically scaled model, %.2f mm on OpenSim 4.1's\n",
              1e3 * a.summary.mean_marker_rms_m, 1e3 * b.summary.mean_marker_rms_m);
  EXPECT_NEAR(fit.model.total_mass_kg(), 72.6, 1e-9);
  EXPECT_LE(a.summary.mean_marker_rms_m, b.summary.mean_marker_rms_m);
  // The option of fitting the walk's frames too (10 of them): offsets are then told apart from the
  // factors by the markers' motion; reported, and no worse on the trial it saw.
  const ScaleFit with_walk = fit_scale_factors(s.model, s.trial, s.setup.placer_tasks, {&walk}, o);
  const IkResult c = inverse_kinematics(with_walk.model, walk, ik.tasks, io);
  std::printf("%s\nwith 10 walking frames: walk1 IK mean marker RMS %.2f mm\n", with_walk.summary.BriefReport().c_str(),
              1e3 * c.summary.mean_marker_rms_m);
  EXPECT_LE(c.summary.mean_marker_rms_m, a.summary.mean_marker_rms_m);
}

}  // namespace
}  // namespace cpgait
