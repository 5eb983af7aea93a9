// Computed muscle control on gait10dof18musc (issue 23): OpenSim's shipped CMC setup through
// `cpgait run-tool` unchanged, against OpenSim 4.1's run of it (../shared/reference/opensim41-here),
// and the model's Thelen variants OpenSim ships results for (an ankle spring, a biarticular path
// spring, a plantar-flexion path actuator), against those results.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>

#include "cpgait/capture/cmc_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "test_support.h"

using namespace cpgait;

namespace {

const std::string kRef = "opensim/gait10dof18musc/OutputReference/";

// RMS of each column over the rows (pErr: rad or m).
std::map<std::string, double> column_rms(const Storage& s) {
  std::map<std::string, double> out;
  for (int c = 1; c < s.num_columns(); ++c) out[s.labels[static_cast<std::size_t>(c)]] = std::sqrt(s.data.col(c).array().square().mean());
  return out;
}

bool is_translation(const std::string& coordinate) { return coordinate == "pelvis_tx" || coordinate == "pelvis_ty"; }

// Runs `cpgait run-tool` on the shipped setup with its model (and constraints file) replaced, every
// path made absolute; returns the results folder.
std::string run_cmc(const std::string& name, const std::string& model_file, const std::string& constraints_file) {
  const std::string ref = refdata::shared_path(kRef);
  std::string setup = text::read_file(ref + "CMC/walk_Setup_CMC.xml");
  setup = std::regex_replace(setup, std::regex("\\.\\./"), ref);
  setup = std::regex_replace(setup, std::regex("<model_file>[^<]*</model_file>"), "<model_file>" + model_file + "</model_file>");
  if (!constraints_file.empty())
    setup = std::regex_replace(setup, std::regex("<constraints_file\\s*/>"), "<constraints_file>" + constraints_file + "</constraints_file>");
  const std::string dir = refdata::temp_dir("cmc_" + name);
  std::ofstream(dir + "/setup.xml") << setup;
  const refdata::CliRun r = refdata::run_cpgait("run-tool " + dir + "/setup.xml --results " + dir + "/out");
  EXPECT_EQ(r.status, 0) << r.output;
  return dir + "/out/";
}

}  // namespace

// The shipped setup (Millard muscles, reserves appended, 5 ms windows, 0.6-1.9 s) next to OpenSim
// 4.1's run. Measured (`cpgait run-tool .../OutputReference/CMC/walk_Setup_CMC.xml`): pErr RMS
// 0.021-0.068 deg and 0.024-0.049 mm against OpenSim's 0.006-0.025 deg and 0.006-0.010 mm. The
// issue's "OpenSim + 0.05 deg (+ 0.5 mm)" holds on every coordinate. The closest, knee_angle_r, is
// 0.066-0.068 against 0.075 at integrator tolerances 7e-4-1.4e-3 (0.073-0.076 with the backward-Euler
// force predictor and no tendon stiffness in the integrator's W). ankle_angle_l was 0.080 (against
// 0.064) while the compliant muscles started at the rigid-tendon activation estimate.
TEST(CmcGait10dof18musc, ShippedSetupTracksAndSharesForcesAsOpenSim41Does) {
  const std::string o41 = refdata::shared_path("opensim41-here/gait10dof18musc_CMC/");
  REQUIRE_REFERENCE(o41 + "walk_subject_pErr.sto");
  REQUIRE_REFERENCE(refdata::shared_path(kRef + "CMC/walk_Setup_CMC.xml"));
  const std::string out = run_cmc("shipped", refdata::shared_path(kRef + "subject01.osim"), "");
  // 1. Tracking: every coordinate within OpenSim 4.1's pErr RMS + 0.05 deg (+ 0.5 mm).
  const auto ours = column_rms(read_storage(out + "walk_subject_pErr.sto"));
  const auto theirs = column_rms(read_storage(o41 + "walk_subject_pErr.sto"));
  ASSERT_EQ(ours.size(), 10u);
  for (const auto& [name, rms] : ours) {
    const double scale = is_translation(name) ? 1000.0 : 180.0 / M_PI;
    std::printf("[ info ] %-17s pErr RMS %.4f (OpenSim 4.1 %.4f) %s\n", name.c_str(), rms * scale, theirs.at(name) * scale,
                is_translation(name) ? "mm" : "deg");
    EXPECT_LE(rms * scale, theirs.at(name) * scale + (is_translation(name) ? 0.5 : 0.05)) << name;
  }
  // 2. Residuals: mean forces and moments within 1 N / 1 N m of OpenSim 4.1's; the reserves no
  // busier than OpenSim's (mean |force|), within 0.005 N m where both are near zero.
  const Storage f = read_storage(out + "walk_subject_Actuation_force.sto"), g = read_storage(o41 + "walk_subject_Actuation_force.sto");
  for (const char* r : {"FX", "FY", "MZ"}) {
    const double a = f.data.col(refdata::required_column(f, r)).mean(), b = g.data.col(refdata::required_column(g, r)).mean();
    std::printf("[ info ] %s mean %.3f (OpenSim 4.1 %.3f)\n", r, a, b);
    EXPECT_NEAR(a, b, 1.0) << r;
  }
  for (int c = 1; c < g.num_columns(); ++c) {
    const std::string& name = g.labels[static_cast<std::size_t>(c)];
    if (name.find("_reserve") == std::string::npos) continue;
    const double a = f.data.col(refdata::required_column(f, name)).cwiseAbs().mean(), b = g.data.col(c).cwiseAbs().mean();
    EXPECT_LE(a, b + 0.005) << name;
  }
  // 3. Muscle forces: each correlates with OpenSim 4.1's at least as well as the shipped (older
  // OpenSim) run does, less 0.05; the mean over the muscles is 0.9 or more.
  const Storage shipped = read_storage(refdata::shared_path(kRef + "CMC/ResultsCMC/walk_subject_Actuation_force.sto"));
  auto at_times = [&](const Storage& s, int col) {  // s's column at g's times, linearly
    std::vector<double> v;
    const Eigen::VectorXd t = s.time();
    for (int k = 0; k < g.num_rows(); ++k) {
      const double tk = g.time()[k];
      const Eigen::Index j = std::clamp<Eigen::Index>(std::upper_bound(t.data(), t.data() + t.size(), tk) - t.data(), 1, t.size() - 1);
      const double w = std::clamp((tk - t[j - 1]) / (t[j] - t[j - 1]), 0.0, 1.0);
      v.push_back((1 - w) * s.data(j - 1, col) + w * s.data(j, col));
    }
    return v;
  };
  double sum = 0;
  int muscles = 0;
  for (int c = 1; c < g.num_columns(); ++c) {
    const std::string& name = g.labels[static_cast<std::size_t>(c)];
    if (name.find("_reserve") != std::string::npos || name == "FX" || name == "FY" || name == "MZ") continue;
    const std::vector<double> reference(g.data.col(c).data(), g.data.col(c).data() + g.num_rows());
    const double r = refdata::correlation(at_times(f, refdata::required_column(f, name)), reference);
    const double r_shipped = refdata::correlation(at_times(shipped, refdata::required_column(shipped, name)), reference);
    std::printf("[ info ] %-13s force r %.3f (shipped run %.3f)\n", name.c_str(), r, r_shipped);
    EXPECT_GE(r, r_shipped - 0.05) << name;
    sum += r;
    ++muscles;
  }
  EXPECT_EQ(muscles, 18);
  EXPECT_GE(sum / muscles, 0.9);
}

// The Thelen-muscle variants with their extra forces, each against the run OpenSim ships with it:
// per coordinate no worse than OpenSim's pErr RMS + 0.05 deg (+ 0.5 mm). Before the CMC optimizer
// counted the model's own passive forces, the path-spring model lost the ankle (31 deg RMS); before
// the muscles kept their states at the first output time, every Thelen variant oscillated at the
// ankle (14-15 deg).
// ankle_angle_l rings at the window period (its error alternates in sign from one 5 ms window to the
// next). While the compliant muscles started at the rigid-tendon activation estimate, the first
// windows' error stayed in that ring and its RMS followed the integrator's error instead of
// converging (0.070 deg at tolerance 1e-3, 0.20-0.23 at 1e-7); started in equilibrium with the first
// forces it is 0.032-0.034 at every tolerance from 1e-3 to 1e-6 (measured).
TEST(CmcGait10dof18musc, ThelenVariantsWithSpringsAndAPathActuatorTrackAsOpenSimDoes) {
  const std::string cmc = refdata::shared_path(kRef + "CMC/");
  REQUIRE_REFERENCE(cmc + "ResultsCMC_PathActuator/walk_subject_pErr.sto");
  struct Variant {
    const char* name;
    const char* model;
    const char* results;
    std::string constraints;
  };
  const Variant variants[] = {
      {"ankle_spring", "subject01_metabolics_spring.osim", "ResultsCMC_AnkleSpring", ""},
      {"path_spring", "subject01_metabolics_path_spring.osim", "ResultsCMC_PathSpring", ""},
      {"path_actuator", "subject01_metabolics_path_actuator.osim", "ResultsCMC_PathActuator",
       refdata::shared_path("opensim/gait10dof18musc/CMC/controls_43p_r.xml")}};
  for (const Variant& v : variants) {
    const std::string out = run_cmc(v.name, cmc + v.model, v.constraints);
    const auto ours = column_rms(read_storage(out + "walk_subject_pErr.sto"));
    const auto theirs = column_rms(read_storage(cmc + v.results + "/walk_subject_pErr.sto"));
    for (const auto& [name, rms] : theirs) {
      const double scale = is_translation(name) ? 1000.0 : 180.0 / M_PI, slack = is_translation(name) ? 0.5 : 0.05;
      ASSERT_TRUE(ours.count(name)) << name;
      std::printf("[ info ] %s %-17s pErr RMS %.4f (OpenSim %.4f)\n", v.name, name.c_str(), ours.at(name) * scale, rms * scale);
      EXPECT_LE(ours.at(name) * scale, rms * scale + slack) << v.name << " " << name;
    }
    if (std::string(v.name) == "path_actuator") {
      // The constraints file pins the assist's control (its min_nodes equal its max_nodes, 0 to
      // 15.5). As OpenSim, each window's control is bounded at the window's start and reached at its
      // end, so the force follows 10 N times the nodes one 5 ms window late.
      const Storage f = read_storage(out + "walk_subject_Actuation_force.sto");
      const int col = refdata::required_column(f, "PlantarFlexAssist");
      const ControlSetSpec c = read_control_set(v.constraints);
      const ControlBounds* b = c.find("PlantarFlexAssist");
      ASSERT_NE(b, nullptr);
      double worst = 0, peak = 0;
      for (int k = 0; k < f.num_rows(); ++k) {
        const double t = f.time()[k];
        if (t < 0.7 || t > 1.85) continue;
        worst = std::max(worst, std::abs(f.data(k, col) - 10 * b->min_at(t - 0.005)));
        peak = std::max(peak, f.data(k, col));
      }
      std::printf("[ info ] PlantarFlexAssist: peak %.1f N, largest difference from 10 N x its pinned control 5 ms before %.3f N\n", peak, worst);
      EXPECT_GT(peak, 150.0);
      EXPECT_LT(worst, 2.0);
    }
  }
}
