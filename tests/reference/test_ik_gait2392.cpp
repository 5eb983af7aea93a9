// Issue acceptance: marker IK on OpenSim's gait2392 subject01 walk, against OpenSim's own results.
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

namespace {

struct Case {
  Model model;
  MarkerTrial trial;
  IkSetup setup;
  IkResult result;
};

const Case& solved() {
  static const Case c = [] {
    Case k;
    k.model = read_osim(refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim")).model;
    k.trial = read_trc(refdata::gait2392("pipeline/subject01_walk1.trc"));
    k.setup = read_ik_setup(refdata::gait2392("pipeline/subject01_Setup_IK.xml"));
    IkOptions o;
    o.time_range_s = k.setup.time_range_s;
    k.result = inverse_kinematics(k.model, k.trial, k.setup.tasks, o);
    return k;
  }();
  return c;
}

// OpenSim's pose for a time, in internal units (the file is in degrees).
Eigen::VectorXd reference_pose(const Model& m, const Storage& ref, double t) {
  int row = -1;
  for (int r = 0; r < ref.num_rows(); ++r)
    if (std::abs(ref.time()[r] - t) < 1e-6) row = r;
  Eigen::VectorXd q(m.num_coordinates());
  if (row < 0) {  // NaN fails every comparison made with it
    ADD_FAILURE() << "no reference row at t=" << t;
    return q.setConstant(std::numeric_limits<double>::quiet_NaN());
  }
  for (int c = 0; c < m.num_coordinates(); ++c)
    q[c] = ref.data(row, refdata::required_column(ref, m.coordinates[c].name)) * (m.coordinates[c].is_angle() ? M_PI / 180 : 1.0);
  return q;
}

#define REQUIRE_GAIT2392()                                                              \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim")); \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/OutputReference/subject01_walk1_ik.mot")); \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_walk1.trc"));                    \
  REQUIRE_REFERENCE(refdata::gait2392("pipeline/subject01_Setup_IK.xml"))

}  // namespace

// Acceptance 1: at every frame our weighted objective is at most that of OpenSim's reference pose
// evaluated on our model (+0.1 %).
TEST(IkGait2392, ObjectiveNoWorseThanOpenSimsPoseAtEveryFrame) {
  REQUIRE_GAIT2392();
  const Case& c = solved();
  const Storage ref = read_storage(refdata::gait2392("pipeline/OutputReference/subject01_walk1_ik.mot"));
  const IkTargets targets = make_ik_targets(c.model, c.trial, c.setup.tasks, {});
  ASSERT_EQ(c.result.q.rows(), 121);
  double ours_rms_sum = 0, theirs_rms_sum = 0, ours_rms_max = 0, theirs_rms_max = 0, worst_ratio = 0;
  for (int i = 0; i < c.result.q.rows(); ++i) {
    const double t = c.result.time_s[i];
    int frame = -1;
    for (int f = 0; f < c.trial.num_frames(); ++f)
      if (c.trial.time_s[f] == t) frame = f;
    ASSERT_GE(frame, 0) << "no trial frame at t=" << t;
    const Eigen::VectorXd q_ref = reference_pose(c.model, ref, t);
    const double theirs = ik_objective(c.model, targets, c.trial, frame, q_ref);
    const double ours = ik_objective(c.model, targets, c.trial, frame, c.result.q.row(i).transpose());
    EXPECT_NEAR(ours, c.result.objective[i], 1e-9 * ours);
    EXPECT_LE(ours, theirs * 1.001) << "frame at t=" << t;
    worst_ratio = std::max(worst_ratio, ours / theirs);
    // Unweighted marker RMS of both poses, as OpenSim reports it.
    IkTargets unweighted = targets;
    for (auto& m : unweighted.markers) m.weight = 1;
    unweighted.coordinates.clear();
    const double n = static_cast<double>(targets.markers.size());
    const double rms_theirs = std::sqrt(ik_objective(c.model, unweighted, c.trial, frame, q_ref) / n);
    theirs_rms_sum += rms_theirs;
    theirs_rms_max = std::max(theirs_rms_max, rms_theirs);
    ours_rms_sum += c.result.marker_rms_m[i];
    ours_rms_max = std::max(ours_rms_max, c.result.marker_rms_m[i]);
  }
  const int n = static_cast<int>(c.result.q.rows());
  // Not asserted beyond the target: the objective is OpenSim's optimum to 1e-8 already (ratio measured 0.99999999).
  std::printf("[ info ] objective ours/OpenSim's: worst frame %.8f\n", worst_ratio);
  std::printf("[ info ] marker RMS mm: ours mean %.3f max %.3f; OpenSim pose mean %.3f max %.3f\n",
              1e3 * ours_rms_sum / n, 1e3 * ours_rms_max, 1e3 * theirs_rms_sum / n, 1e3 * theirs_rms_max);
}

// Acceptance 2: rotational coordinates within 1 deg RMS of OpenSim's reference, pelvis translations
// within 2 mm RMS (the targets); regression bounds 0.03 deg and 0.012 mm, about 5x the worst figures
// measured when they were set (knee_angle_l 0.0062 deg, pelvis_tx/ty 0.0023 mm).
TEST(IkGait2392, CoordinatesMatchOpenSimsReference) {
  REQUIRE_GAIT2392();
  const Case& c = solved();
  const Storage ref = read_storage(refdata::gait2392("pipeline/OutputReference/subject01_walk1_ik.mot"));
  for (int k = 0; k < c.model.num_coordinates(); ++k) {
    const Coordinate& co = c.model.coordinates[k];
    double sum2 = 0;
    for (int i = 0; i < c.result.q.rows(); ++i) {
      const double d = c.result.q(i, k) - reference_pose(c.model, ref, c.result.time_s[i])[k];
      sum2 += d * d;
    }
    const double rms = std::sqrt(sum2 / c.result.q.rows());
    if (co.is_angle()) {
      EXPECT_TRUE(refdata::within_target_and_regression(rms * 180 / M_PI, 1.0, 0.03)) << co.name << " (deg)";
      std::printf("[ info ] %-18s RMS difference %.4f deg\n", co.name.c_str(), rms * 180 / M_PI);
    } else {
      EXPECT_TRUE(refdata::within_target_and_regression(rms * 1e3, 2.0, 0.012)) << co.name << " (mm)";
      std::printf("[ info ] %-18s RMS difference %.4f mm\n", co.name.c_str(), rms * 1e3);
    }
  }
}

// OpenSim 4.1 run here on the same files wrote its per-frame marker errors. These are unweighted RMS,
// while both solvers minimise the weighted sum, so ours may lie on either side of OpenSim's (the weighted
// objective is held one-sided against OpenSim's pose above). Held both ways: within 0.2 mm (the target)
// and 0.06 mm (the regression bound, 4x the 0.015 mm measured either way when it was set).
TEST(IkGait2392, MarkerErrorsMatchOpenSim41PerFrame) {
  REQUIRE_GAIT2392();
  const std::string path = refdata::shared_path("opensim41-here/IK/subject01_ik_marker_errors.sto");
  REQUIRE_REFERENCE(path);
  const Case& c = solved();
  const Storage e = read_storage(path);
  ASSERT_EQ(e.num_rows(), c.result.q.rows());
  const int col = e.column("marker_error_RMS");
  ASSERT_GE(col, 0);
  double largest_excess = -1, largest_deficit = 0;
  for (int i = 0; i < e.num_rows(); ++i) {
    EXPECT_NEAR(e.time()[i], c.result.time_s[i], 1e-6);
    const double d = c.result.marker_rms_m[i] - e.data(i, col);
    largest_excess = std::max(largest_excess, d);
    largest_deficit = std::max(largest_deficit, -d);
  }
  EXPECT_TRUE(refdata::within_target_and_regression(largest_excess * 1e3, 0.2, 0.06)) << "mm above OpenSim 4.1's";
  EXPECT_TRUE(refdata::within_target_and_regression(largest_deficit * 1e3, 0.2, 0.06)) << "mm below OpenSim 4.1's";
  std::printf("[ info ] per-frame marker RMS vs OpenSim 4.1: ours larger by at most %.4f mm, smaller by at most %.4f mm\n",
              largest_excess * 1e3, largest_deficit * 1e3);
}
