// The autonomous gait (issue 22) on gait10dof18musc, a planar model with 18 Millard muscles, as a user
// runs it: `cpgait run` with the gait stage tuning its controller (no residuals), then `cpgait gait`
// replaying the tuned CPG at other speed knobs. The issue's targets: 10 s without falling, strides of
// the cycle / speed within 5 %, rotations within 5 deg RMS of the trial's cycle, walking speed rising
// with the knob; and walk -> stand: it stops within two strides and stands 3 s with its centre of
// mass over its feet.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cpgait/capture/text_lines.h"
#include "test_support.h"

using namespace cpgait;

// Measured (this test: 600 simulations over rounds of 5 and 10 s, 60 s on 2 cores; the tuner's
// starting gains already walked 10 s, the search improved the tracking): 10 s at 0.8, 1 and 1.2;
// strides 2.3 %, 0.0 %, 1.5 % off cycle / speed; 0.83, 1.07, 1.33 m/s. Knob 1's controller walks the
// other knobs untuned here, so the tuning has no cycle term: with the stage's default weight (10) the
// knob-1 walker fell at 0.8 (4.87 s), at 1.2 (8.58 s) and after the 2 cm step down (8.73 s)
// (docs/gait-tuning.md, "The ankle strategy and the cycle term as the stage's defaults").
TEST(GaitGait10dof, TunedCpgWalksTenSecondsAtEverySpeedKnobAndStops) {
  const std::string d = refdata::shared_path("opensim/gait10dof18musc/");
  for (const char* f : {"OutputReference/subject01.osim", "ExperimentalData/subject01_walk.trc", "ExperimentalData/subject01_walk_grf.mot",
                        "ExperimentalData/subject01_walk_grf.xml", "IK/walk_Setup_IK.xml"})
    REQUIRE_REFERENCE(d + f);
  const std::string dir = refdata::temp_dir("gait10dof_autonomous");
  std::ofstream(dir + "/options.json")
      << R"({"gait": {"residuals": false, "phase_reference": true, "tune_evaluations": 600, "tune_horizon_s": 10, "tune_rounds": 2, "duration_s": 10,
             "foot_spheres": 2, "tune_restarts": 0, "tune_rotation_limit_deg": 0, "tune_stop_at": [], "tune_cycle_weight": 0, "speed_knobs": []}})";
  const refdata::CliRun run = refdata::run_cpgait("run --model " + d + "OutputReference/subject01.osim --markers " + d +
                                                  "ExperimentalData/subject01_walk.trc --grf " + d + "ExperimentalData/subject01_walk_grf.mot --loads " +
                                                  d + "ExperimentalData/subject01_walk_grf.xml --ik-tasks " + d + "IK/walk_Setup_IK.xml --options " +
                                                  dir + "/options.json -o " + dir + "/run");
  ASSERT_EQ(run.status, 0) << run.output;
  const nlohmann::json staged = nlohmann::json::parse(text::read_file(dir + "/run/subject01_walk_gait.json"));
  std::printf("[ info ] tuning: %s\n", staged["tuning"].dump().c_str());
  EXPECT_TRUE(staged["fell_at_s"].is_null()) << staged.dump();
  EXPECT_FALSE(staged["pelvis_residuals"].get<bool>());
  // It walks by its own stability, not by the integration error of the tolerance it was tuned at
  // (subject01's first controllers did not): the stage's check at 5e-4 and 2e-3.
  ASSERT_EQ(staged["tolerance_check"].size(), 2u) << staged.dump();
  for (const auto& check : staged["tolerance_check"]) {
    EXPECT_TRUE(check["fell_at_s"].is_null()) << check.dump();
    EXPECT_NEAR(check["simulated_s"].get<double>(), 10.0, 1e-9) << check.dump();
  }
  const double cycle_s = nlohmann::json::parse(text::read_file(dir + "/run/subject01_walk_cpg.json"))["cycle_s"].get<double>();
  double last_speed = 0;
  for (double knob : {0.8, 1.0, 1.2}) {
    char out[64];
    std::snprintf(out, sizeof out, "/speed_%.1f", knob);
    const refdata::CliRun g = refdata::run_cpgait("gait --model " + d + "OutputReference/subject01.osim --cpg " + dir +
                                                  "/run/subject01_walk_cpg_tuned.json --kinematics " + dir + "/run/subject01_walk_ik.mot --duration 10 --speed " +
                                                  std::to_string(knob) + " -o " + dir + out);
    ASSERT_EQ(g.status, 0) << g.output;
    const nlohmann::json m = nlohmann::json::parse(text::read_file(dir + out + "_gait.json"));
    std::printf("[ info ] speed knob %.1f: stride %.3f s, %.3f m, %.2f m/s, fell at %s\n", knob, m["stride_time_s"].get<double>(),
                m["stride_length_m"].get<double>(), m["speed_m_s"].get<double>(), m["fell_at_s"].dump().c_str());
    EXPECT_TRUE(m["fell_at_s"].is_null()) << knob;
    EXPECT_GE(m["heel_strikes_s"]["right"].size(), static_cast<std::size_t>(std::floor(10 * knob / cycle_s))) << knob;
    EXPECT_NEAR(m["stride_time_s"].get<double>() * knob / cycle_s, 1.0, 0.05) << knob;
    for (const auto& [name, rms] : m["tracking_rms_deg_or_m"].items()) {
      if (name.rfind("pelvis_t", 0) != 0) {
        EXPECT_LT(rms.get<double>(), 5.0) << knob << ": " << name;
      }
    }
    EXPECT_GT(m["speed_m_s"].get<double>(), last_speed) << knob;
    last_speed = m["speed_m_s"].get<double>();
  }
  // Over the issue's ground steps placed mid-walk.
  for (const char* replay : {"--step-height -0.02 --step-time 5", "--step-height 0.01 --step-time 5"}) {
    const refdata::CliRun r = refdata::run_cpgait("gait --model " + d + "OutputReference/subject01.osim --cpg " + dir +
                                                  "/run/subject01_walk_cpg_tuned.json --kinematics " + dir +
                                                  "/run/subject01_walk_ik.mot --duration 10 " + replay + " -o " + dir + "/perturbed");
    ASSERT_EQ(r.status, 0) << r.output;
    const nlohmann::json g = nlohmann::json::parse(text::read_file(dir + "/perturbed_gait.json"));
    EXPECT_TRUE(g["fell_at_s"].is_null()) << replay << ": fell at " << g["fell_at_s"];
  }
  // Walk -> stand from 4.5 s: the walk freezes at the next stop phase (within a cycle), comes to rest
  // within two strides of that and stands on to the end (5 s or more here).
  const refdata::CliRun stop = refdata::run_cpgait("gait --model " + d + "OutputReference/subject01.osim --cpg " + dir +
                                                   "/run/subject01_walk_cpg_tuned.json --kinematics " + dir +
                                                   "/run/subject01_walk_ik.mot --duration 10 --stop-at 4.5 -o " + dir + "/stop");
  ASSERT_EQ(stop.status, 0) << stop.output;
  const nlohmann::json m = nlohmann::json::parse(text::read_file(dir + "/stop_gait.json"));
  std::printf("[ info ] walk -> stand: %s\n", m["stand"].dump().c_str());
  EXPECT_TRUE(m["fell_at_s"].is_null()) << m.dump();
  ASSERT_TRUE(m.contains("stand")) << m.dump();
  const double frozen = m["stand"]["frozen_at_s"].get<double>();
  EXPECT_GE(frozen, 4.5);
  EXPECT_LT(frozen, 4.5 + cycle_s);
  ASSERT_TRUE(m["stand"]["stopped_at_s"].is_number()) << m.dump();
  EXPECT_LT(m["stand"]["stopped_at_s"].get<double>() - frozen, 2 * cycle_s);
  EXPECT_GE(m["stand"]["stood_s"].get<double>(), 3.0);
  std::filesystem::remove_all(dir);
}
