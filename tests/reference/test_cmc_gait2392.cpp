// Issue 4 acceptance: computed muscle control on OpenSim's subject01 CMC setup (adjusted model,
// RRA kinematics, 0.5-2.0 s), compared with OpenSim's own CMC results.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

namespace {

struct Subject01Cmc {
  Model model;
  std::vector<ActuatorSpec> specs;
  std::vector<CmcJointTask> tasks;
  ControlSetSpec constraints;
  Storage kinematics;
};

Subject01Cmc load(const std::string& pl) {
  Subject01Cmc s;
  s.model = read_osim(pl + "OutputReference/subject01_simbody_adjusted.osim").model;
  s.specs = read_actuators(pl + "gait2392_CMC_Actuators.xml");
  s.tasks = read_cmc_tasks(pl + "gait2392_CMC_Tasks.xml");
  s.constraints = read_control_set(pl + "gait2392_CMC_ControlConstraints.xml");
  s.kinematics = read_storage(pl + "OutputReference/ResultsRRA/subject01_walk1_RRA_Kinematics_q.sto");
  return s;
}

double rms_of_column(const Storage& s, int col, double from_s) {
  double sum = 0;
  int n = 0;
  for (int i = 0; i < s.num_rows(); ++i)
    if (s.time()[i] >= from_s - 1e-9) {
      sum += s.data(i, col) * s.data(i, col);
      ++n;
    }
  return std::sqrt(sum / std::max(1, n));
}

// Value of column `col` at time t, linearly interpolated.
double at(const Storage& s, int col, double t) {
  const Eigen::VectorXd time = s.time();
  const int n = s.num_rows();
  int i = static_cast<int>(std::upper_bound(time.data(), time.data() + n, t) - time.data()) - 1;
  i = std::clamp(i, 0, n - 2);
  const double w = std::clamp((t - time[i]) / (time[i + 1] - time[i]), 0.0, 1.0);
  return (1 - w) * s.data(i, col) + w * s.data(i + 1, col);
}

double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) ma += a[i] / n, mb += b[i] / n;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb + 1e-300);
}

}  // namespace

TEST(CmcGait2392, TracksLikeOpenSimWithMeasuredLoads) {
  const std::string pl = refdata::gait2392("pipeline/");
  const std::string ref = pl + "OutputReference/ResultsCMC/subject01_walk1_";
  for (const auto& p : {pl + "subject01_Setup_CMC.xml", ref + "pErr.sto", ref + "Actuation_force.sto", ref + "avgResiduals.txt"})
    REQUIRE_REFERENCE(p);
  const Subject01Cmc in = load(pl);
  const Model& m = in.model;
  const ResolvedActuators actuators(m, in.specs);
  const AppliedLoads loads(m, read_external_loads(pl + "subject01_walk1_grf.xml"), read_storage(pl + "subject01_walk1_grf.mot"));
  ComputedMuscleControlOptions o;
  o.time_range_s = std::make_pair(0.5, 2.0);
  const ComputedMuscleControlResult r =
      computed_muscle_control(m, in.kinematics, &loads, nullptr, actuators, in.tasks, &in.constraints, o);
  std::printf("[ info ] %s\n", r.summary.BriefReport().c_str());
  EXPECT_EQ(r.summary.external_forces, "measured loads");
  EXPECT_EQ(r.summary.windows_infeasible, 0);

  // 1. Tracking error, RMS over the windows from 0.53 s (OpenSim's first output), next to OpenSim's.
  const Storage ref_perr = read_storage(ref + "pErr.sto");
  const Eigen::VectorXd rms = r.position_error_rms();
  int worse_than_opensim = 0;
  for (int c = 0; c < m.num_coordinates(); ++c) {
    const auto& co = m.coordinates[c];
    const int col = ref_perr.column(co.name);
    ASSERT_GE(col, 0) << co.name;
    const double theirs = rms_of_column(ref_perr, col, 0.53);
    const double scale = co.is_angle() ? 180 / M_PI : 100;
    const bool mtp = co.name.rfind("mtp_", 0) == 0;
    std::printf("[ info ] pErr RMS %-18s ours %6.3f  OpenSim %6.3f %s\n", co.name.c_str(), rms[c] * scale, theirs * scale,
                co.is_angle() ? "deg" : "cm");
    if (rms[c] > theirs) ++worse_than_opensim;
    // The bound: under 1 deg for rotations and 1 cm for translations; the mtp angles, where
    // OpenSim's own run is ~5 deg off, are reported next to OpenSim's, not held to it.
    if (!mtp) {
      EXPECT_LT(rms[c] * scale, 1.0) << co.name << (co.is_angle() ? " (deg)" : " (cm)");
    }
  }
  std::printf("[ info ] coordinates tracked less closely than OpenSim: %d of %d\n", worse_than_opensim, m.num_coordinates());

  // 2. Average residuals next to OpenSim's.
  std::ifstream f(ref + "avgResiduals.txt");
  std::stringstream text;
  text << f.rdbuf();
  for (const auto& [name, value] : r.average_residuals()) {
    const auto p = text.str().find(name + " average = ");
    ASSERT_NE(p, std::string::npos) << name;
    const double theirs = std::stod(text.str().substr(p + name.size() + 11));
    std::printf("[ info ] average residual %s ours %8.3f  OpenSim %8.3f %s\n", name.c_str(), value, theirs,
                std::abs(value) <= std::abs(theirs) ? "" : "(larger)");
    EXPECT_LT(std::abs(value), 25.0) << name << ": an average residual this large means the dynamics disagree";
  }

  // 3. Muscle forces against OpenSim's, for muscles whose reference peak exceeds 10 % of max force.
  const Storage ref_force = read_storage(ref + "Actuation_force.sto");
  std::vector<std::pair<double, std::string>> corr;
  for (int k = 0; k < static_cast<int>(m.muscles.size()); ++k) {
    const int col = ref_force.column(m.muscles[k].name);
    ASSERT_GE(col, 0) << m.muscles[k].name;
    std::vector<double> ours, theirs;
    double peak = 0;
    for (int i = 0; i < ref_force.num_rows(); ++i) {
      const double t = ref_force.time()[i];
      if (t < r.time_s.front() || t > r.time_s.back()) continue;
      theirs.push_back(ref_force.data(i, col));
      peak = std::max(peak, ref_force.data(i, col));
      const auto j = std::lower_bound(r.time_s.begin(), r.time_s.end(), t) - r.time_s.begin();
      const int j1 = std::clamp(static_cast<int>(j), 1, static_cast<int>(r.time_s.size()) - 1);
      const double w = (t - r.time_s[j1 - 1]) / (r.time_s[j1] - r.time_s[j1 - 1]);
      ours.push_back((1 - w) * r.muscle_force_N(j1 - 1, k) + w * r.muscle_force_N(j1, k));
    }
    if (peak > 0.1 * m.muscles[k].max_isometric_force_N) corr.push_back({correlation(ours, theirs), m.muscles[k].name});
  }
  std::sort(corr.begin(), corr.end());
  const auto good = std::count_if(corr.begin(), corr.end(), [](const auto& c) { return c.first >= 0.9; });
  std::printf("[ info ] muscle force correlation with OpenSim >= 0.9: %ld of %zu (reference peak > 10%% of max force)\n",
              static_cast<long>(good), corr.size());
  for (std::size_t i = 0; i < std::min<std::size_t>(5, corr.size()); ++i)
    std::printf("[ info ] lowest force correlation %zu: %-12s r = %.3f\n", i + 1, corr[i].second.c_str(), corr[i].first);
  (void)at;
}

// Acceptance 4: the same trial without force plates, on the default contact spheres (two per foot),
// the ground placed under the recorded feet. Reported; held only to staying on the path.
TEST(CmcGait2392, WithoutGrfOnContactSpheres) {
  const std::string pl = refdata::gait2392("pipeline/");
  REQUIRE_REFERENCE(pl + "gait2392_CMC_Tasks.xml");
  const Subject01Cmc in = load(pl);
  const Model& m = in.model;
  const ResolvedActuators actuators(m, in.specs);
  const ContactSet feet = default_foot_contacts(m);
  ComputedMuscleControlOptions o;
  o.time_range_s = std::make_pair(0.5, 2.0);
  const ComputedMuscleControlResult r =
      computed_muscle_control(m, in.kinematics, nullptr, &feet, actuators, in.tasks, &in.constraints, o);
  std::printf("[ info ] no GRF: %s\n", r.summary.BriefReport().c_str());
  EXPECT_EQ(r.summary.external_forces, "contact spheres");
  const Eigen::VectorXd rms = r.position_error_rms();
  double worst = 0;
  std::string worst_name;
  for (int c = 0; c < m.num_coordinates(); ++c) {
    const auto& co = m.coordinates[c];
    if (!co.is_angle() || co.name.rfind("mtp_", 0) == 0) continue;
    if (rms[c] > worst) worst = rms[c], worst_name = co.name;
  }
  std::printf("[ info ] no GRF: worst rotational tracking error (mtp aside) %s %.3f deg; mtp_r %.2f, mtp_l %.2f deg\n",
              worst_name.c_str(), worst * 180 / M_PI, rms[m.coordinate_index("mtp_angle_r")] * 180 / M_PI,
              rms[m.coordinate_index("mtp_angle_l")] * 180 / M_PI);
  for (const auto& [name, value] : r.average_residuals()) std::printf("[ info ] no GRF: average residual %s %8.2f\n", name.c_str(), value);
  EXPECT_LT(worst * 180 / M_PI, 3.0) << worst_name;
}
