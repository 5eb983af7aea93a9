#include <gtest/gtest.h>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/ik_setup.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

using refdata::walker;

TEST(Ik, RecoversExactCoordinatesFromNoiseFreeMarkers) {
  const auto synth = fixtures::synthesize_trial(walker(), {});
  const IkResult r = inverse_kinematics(walker(), synth.markers, {});
  ASSERT_EQ(r.q.rows(), synth.markers.num_frames());
  const double err = (r.q - synth.q).cwiseAbs().maxCoeff();
  EXPECT_LT(err, 1e-6) << "largest coordinate error (rad or m)";
  EXPECT_LT(r.marker_max_m.maxCoeff(), 1e-7);
  EXPECT_EQ(r.summary.frames_not_converged, 0);
}

TEST(Ik, SkipsMissingMarkersAndHoldsLockedCoordinates) {
  fixtures::SyntheticTrialOptions o;
  o.gap_fraction = 0.4;
  const auto synth = fixtures::synthesize_trial(walker(), o);
  ASSERT_FALSE(synth.markers.gaps().empty());
  const IkResult r = inverse_kinematics(walker(), synth.markers, {});
  EXPECT_LT((r.q - synth.q).cwiseAbs().maxCoeff(), 1e-5);
  const int locked = walker().coordinate_index("lumbar_rotation");
  EXPECT_EQ((r.q.col(locked).array() - walker().coordinates[locked].default_value).abs().maxCoeff(), 0.0);
  // Missing markers show as NaN errors, not zeros.
  bool saw_nan = false;
  for (int i = 0; i < r.marker_error_m.size(); ++i) saw_nan |= std::isnan(r.marker_error_m.data()[i]);
  EXPECT_TRUE(saw_nan);
}

TEST(Ik, ClampedCoordinatesStayInRange) {
  // Push the trial's knee past its range by moving the ankle markers; the clamped knee must stop at
  // its bound while the unclamped hips move freely.
  auto synth = fixtures::synthesize_trial(walker(), {});
  const int knee = walker().coordinate_index("knee_angle_r");
  for (const char* name : {"R.Ankle.Lat", "R.Heel", "R.Midfoot", "R.Toe"}) {
    const int m = synth.markers.marker_index(name);
    for (int f = 0; f < synth.markers.num_frames(); ++f) synth.markers.position_m(f, m).x() += 0.5;
  }
  const IkResult r = inverse_kinematics(walker(), synth.markers, {});
  EXPECT_LE(r.q.col(knee).maxCoeff(), walker().coordinates[knee].range_max + 1e-12);
  EXPECT_GE(r.q.col(knee).minCoeff(), walker().coordinates[knee].range_min - 1e-12);
  IkOptions free;
  free.bounds = IkOptions::Bounds::kNone;
  const IkResult u = inverse_kinematics(walker(), synth.markers, {}, free);
  EXPECT_GT(u.q.col(knee).maxCoeff(), walker().coordinates[knee].range_max + 0.05);
  // Bounds never lower the objective.
  EXPECT_GE(r.objective.sum(), u.objective.sum() - 1e-9);
}

TEST(Ik, WeightsTimeRangeAndCoordinateTasks) {
  const auto synth = fixtures::synthesize_trial(walker(), {});
  IkTaskSet tasks;
  for (const auto& m : walker().markers) tasks.markers.push_back({m.name, m.name == "R.Toe" ? 0.0 : 2.0, true});
  tasks.markers.push_back({"Not.A.Marker", 1.0, true});
  IkCoordinateTask ct;
  ct.name = "hip_rotation_l";
  ct.weight = 1e6;
  ct.value_type = IkCoordinateTask::ValueType::kManualValue;
  ct.value = 0.2;
  tasks.coordinates.push_back(ct);
  IkOptions o;
  o.time_range_s = std::make_pair(0.5, 1.0);
  const IkResult r = inverse_kinematics(walker(), synth.markers, tasks, o);
  EXPECT_EQ(r.q.rows(), 51);
  EXPECT_DOUBLE_EQ(r.time_s.front(), 0.5);
  EXPECT_EQ(std::find(r.marker_names.begin(), r.marker_names.end(), "R.Toe"), r.marker_names.end());
  const int hr = walker().coordinate_index("hip_rotation_l");
  EXPECT_LT((r.q.col(hr).array() - 0.2).abs().maxCoeff(), 0.01);  // the heavy task wins
  bool warned = false;
  for (const auto& w : r.summary.warnings) warned |= w.find("Not.A.Marker") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(Ik, UnusableInputsAreClearErrors) {
  auto synth = fixtures::synthesize_trial(walker(), {});
  IkOptions o;
  o.time_range_s = std::make_pair(10.0, 11.0);
  EXPECT_THROW(inverse_kinematics(walker(), synth.markers, {}, o), InputError);
  IkTaskSet tasks;
  tasks.coordinates.push_back({"no_such_coordinate", 1.0, true, IkCoordinateTask::ValueType::kDefaultValue, 0});
  EXPECT_THROW(inverse_kinematics(walker(), synth.markers, tasks), InputError);
  for (auto& n : synth.markers.marker_names) n += "_x";
  EXPECT_THROW(inverse_kinematics(walker(), synth.markers, {}), InputError);
}

TEST(Ik, TablesUseOpenSimUnitsAndNames) {
  const auto synth = fixtures::synthesize_trial(walker(), {});
  const IkResult r = inverse_kinematics(walker(), synth.markers, {});
  const Storage q = ik_coordinates_table(walker(), r);
  EXPECT_TRUE(q.in_degrees.value());
  const int knee = walker().coordinate_index("knee_angle_r");
  EXPECT_NEAR(q.data(3, refdata::required_column(q, "knee_angle_r")), r.q(3, knee) * 180 / M_PI, 1e-12);
  EXPECT_NEAR(q.data(3, refdata::required_column(q, "pelvis_tx")), r.q(3, walker().coordinate_index("pelvis_tx")), 1e-15);
  const Storage e = ik_marker_errors_table(r);
  EXPECT_EQ(e.labels[1], "total_squared_error");
  EXPECT_EQ(e.labels[2], "marker_error_RMS");
  EXPECT_EQ(e.labels[3], "marker_error_max");
  EXPECT_EQ(e.labels[4], "worst_marker");
  EXPECT_EQ(e.num_columns(), 5 + static_cast<int>(r.marker_names.size()));
  for (int i = 0; i < e.num_rows(); ++i) {
    const int worst = static_cast<int>(e.data(i, 4));
    ASSERT_GE(worst, 1);
    EXPECT_DOUBLE_EQ(e.data(i, 4 + worst), e.data(i, 3));  // the named marker's error is the max
  }
}

TEST(Ik, TaskFilesInJsonAndXml) {
  const IkTaskSet j = parse_ik_tasks_json(R"({"markers": {"R.ASIS": 10, "Top.Head": {"weight": 0.1, "apply": false}},
      "coordinates": {"subtalar_angle_r": {"weight": 1000, "value_type": "manual_value", "value": 0.1}}})",
                                          "tasks.json");
  ASSERT_EQ(j.markers.size(), 2u);
  EXPECT_EQ(j.markers[0].name, "R.ASIS");
  EXPECT_DOUBLE_EQ(j.markers[0].weight, 10);
  EXPECT_FALSE(j.markers[1].apply);
  ASSERT_EQ(j.coordinates.size(), 1u);
  EXPECT_EQ(j.coordinates[0].value_type, IkCoordinateTask::ValueType::kManualValue);
  EXPECT_DOUBLE_EQ(j.coordinates[0].value, 0.1);
  EXPECT_THROW(parse_ik_tasks_json("[1, 2]", "t.json"), InputError);
  // A mistyped task names its field.
  auto field_of = [](const std::string& text) {
    try {
      parse_ik_tasks_json(text, "t.json");
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "t.json");
      return e.field();
    }
    return std::string("(accepted)");
  };
  EXPECT_EQ(field_of(R"({"coordinates": {"x": {"value_type": "guess"}}})"), "coordinates.x.value_type");
  EXPECT_EQ(field_of(R"({"markers": {"RASI": {"weight": "heavy"}}})"), "markers.RASI.weight");
  EXPECT_EQ(field_of(R"({"markers": {"RASI": "heavy"}})"), "markers.RASI");
  EXPECT_EQ(field_of(R"({"coordinates": {"knee": {"apply": 1.5}}})"), "coordinates.knee.apply");
  EXPECT_EQ(field_of(R"({"markers": ["RASI"]})"), "markers");
}

TEST(IkReference, ReadsOpenSimsIkSetup) {
  const std::string path = refdata::gait2392("pipeline/subject01_Setup_IK.xml");
  REQUIRE_REFERENCE(path);
  const IkSetup s = read_ik_setup(path);
  EXPECT_EQ(s.name, "subject01");
  EXPECT_EQ(s.model_file, "subject01_simbody.osim");
  EXPECT_EQ(s.marker_file, "subject01_walk1.trc");
  ASSERT_TRUE(s.time_range_s.has_value());
  EXPECT_DOUBLE_EQ(s.time_range_s->first, 0.5);
  EXPECT_DOUBLE_EQ(s.time_range_s->second, 2.5);
  EXPECT_EQ(s.output_motion_file, "subject01_walk1_ik.mot");
  EXPECT_EQ(s.tasks.coordinates.size(), 4u);
  double head = -1;
  for (const auto& t : s.tasks.markers)
    if (t.name == "Top.Head") head = t.weight;
  EXPECT_DOUBLE_EQ(head, 0.1);
}

TEST(Ik, FromFileCoordinateTaskFollowsTheCoordinateFile) {
  const auto synth = fixtures::synthesize_trial(walker(), {});
  // A coordinate file (degrees, at half the trial's rate) asking hip_rotation_l to follow 5*sin(t).
  Storage ref;
  ref.in_degrees = true;
  ref.labels = {"time", "hip_rotation_l"};
  ref.data.resize(101, 2);
  for (int r = 0; r <= 100; ++r) ref.data.row(r) << r * 0.02, 5.0 * std::sin(r * 0.02);
  IkTaskSet tasks;
  IkCoordinateTask ct;
  ct.name = "hip_rotation_l";
  ct.weight = 1e7;
  ct.value_type = IkCoordinateTask::ValueType::kFromFile;
  tasks.coordinates.push_back(ct);
  const IkResult r = inverse_kinematics(walker(), synth.markers, tasks, {}, &ref);
  const int c = walker().coordinate_index("hip_rotation_l");
  for (int i = 0; i < r.q.rows(); i += 7)
    EXPECT_NEAR(r.q(i, c) * 180 / M_PI, 5.0 * std::sin(r.time_s[i]), 0.02) << "t=" << r.time_s[i];
  EXPECT_THROW(inverse_kinematics(walker(), synth.markers, tasks), InputError);  // no file given
}

// A CoordinateCouplerConstraint (leg6dof9musc's patella angle = f(knee angle)), with a curved
// function and a marker on the patella: IK moves the knee through the patella's marker too, and the
// coupled coordinate follows its function exactly.
TEST(IkReference, CoupledCoordinateFollowsItsFunction) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/CMC/leg6dof9musc.osim");
  REQUIRE_REFERENCE(path);
  Model m = read_osim(path).model;
  ASSERT_EQ(m.couplers.size(), 1u);
  CoordinateCoupler& c = m.couplers[0];
  EXPECT_EQ(m.coordinates[c.dependent].name, "knee_angle_pat_r");
  EXPECT_EQ(m.coordinates[c.independent].name, "knee_angle_r");
  c.function = Function::simm_spline({-2.1, -1.0, 0.0, 0.2}, {-1.4, -0.8, 0.05, 0.1});
  Marker pat;
  pat.name = "PAT";
  pat.body = m.body_index("patella_r");
  pat.location_m = Eigen::Vector3d(0.03, 0.01, 0.0);
  m.markers.push_back(pat);
  fixtures::SyntheticTrialOptions o;
  o.duration_s = 0.5;
  const auto synth = fixtures::synthesize_trial(m, o);
  const IkResult r = inverse_kinematics(m, synth.markers, {});
  double worst_coupling = 0, worst = 0;
  for (int f = 0; f < r.q.rows(); ++f) {
    worst_coupling = std::max(worst_coupling, std::abs(r.q(f, c.dependent) - c.function.value(r.q(f, c.independent))));
    worst = std::max(worst, (r.q.row(f) - synth.q.row(f)).cwiseAbs().maxCoeff());
  }
  std::printf("coupled IK: coupling %.1e, largest coordinate error %.1e over %d frames\n", worst_coupling, worst,
              static_cast<int>(r.q.rows()));
  EXPECT_LT(worst_coupling, 1e-9);
  EXPECT_LT(worst, 1e-5);
  EXPECT_EQ(r.summary.frames_not_converged, 0);

  // With 5 mm of marker noise the fit is a least-squares optimum over the knee angle as the patella
  // follows it: the squared marker error's derivative along the knee (central differences) vanishes
  // there. A coupled Jacobian without f' converges elsewhere.
  o.noise_m = 0.005;
  const auto noisy = fixtures::synthesize_trial(m, o);
  const IkResult rn = inverse_kinematics(m, noisy.markers, {});
  KinematicsWorkspace<double> ws(m);
  auto squared_error = [&](Eigen::VectorXd q, int f) {
    apply_coordinate_couplers(m, q.data());
    forward_kinematics(m, q.data(), ws);
    double sum = 0;
    for (int k = 0; k < noisy.markers.num_markers(); ++k) {
      const int mk = m.marker_index(noisy.markers.marker_names[k]);
      if (mk >= 0) sum += (marker_position(m, mk, ws) - noisy.markers.position_m(f, k)).squaredNorm();
    }
    return sum;
  };
  double worst_gradient = 0;
  for (int f = 0; f < rn.q.rows(); f += 10) {
    Eigen::VectorXd qp = rn.q.row(f).transpose(), qm = qp;
    qp[c.independent] += 1e-5;
    qm[c.independent] -= 1e-5;
    worst_gradient = std::max(worst_gradient, std::abs(squared_error(qp, f) - squared_error(qm, f)) / 2e-5);
  }
  std::printf("noisy coupled IK: largest d(squared error)/d(knee) %.1e m^2/rad\n", worst_gradient);
  // Measured 2.7e-7 (the solver's stopping tolerances); with the coupled Jacobian's f' replaced by 1,
  // 1.3e-5.
  EXPECT_LT(worst_gradient, 2e-6);
}
