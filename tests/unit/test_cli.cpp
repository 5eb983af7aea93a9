// The cpgait executable end to end: subcommands write OpenSim files, bad input exits with a message.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>

#include "cpgait/capture/storage.h"
#include "cpgait/fixtures/tag_footage.h"
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <sys/stat.h>
#include <thread>
#include "c3d_writer.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/trc.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace {
using cpgait::refdata::CliRun;
CliRun run(const std::string& args) { return cpgait::refdata::run_cpgait(args); }

// A run refused with `status`, its message naming `what` (a field, an option).
void expect_refused(const CliRun& r, int status, const std::string& what) {
  EXPECT_EQ(r.status, status) << r.output;
  EXPECT_NE(r.output.find(what), std::string::npos) << r.output;
}
}  // namespace

TEST(Cli, HelpStatesInputsOutputsAndUnits) {
  const CliRun r = run("--help");
  EXPECT_EQ(r.status, 0);
  for (const char* sub : {"ik", "run-tool", "demo", "model", "synth"}) EXPECT_NE(r.output.find(sub), std::string::npos) << sub;
  const CliRun ik = run("ik --help");
  EXPECT_NE(ik.output.find("degrees"), std::string::npos);
  EXPECT_NE(ik.output.find("--markers"), std::string::npos);
}

TEST(Cli, SynthThenIkWritesOpenSimFiles) {
  const std::string dir = cpgait::refdata::temp_dir("cli_ik");
  const std::string model = cpgait::refdata::fixture("models/walker.osim");
  ASSERT_EQ(run("synth --model " + model + " --duration 0.5 -o " + dir + "/t.trc").status, 0);
  const CliRun r = run("ik --model " + model + " --markers " + dir + "/t.trc -o " + dir);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("frames/s"), std::string::npos);
  const cpgait::Storage q = cpgait::read_storage(dir + "/t_ik.mot");
  const cpgait::Storage truth = cpgait::read_storage(dir + "/t.trc.truth.mot");
  ASSERT_EQ(q.num_rows(), truth.num_rows());
  const int c = q.column("hip_flexion_r");
  EXPECT_LT((q.data.col(c) - truth.data.col(cpgait::refdata::required_column(truth, "hip_flexion_r"))).cwiseAbs().maxCoeff(), 1e-3);  // degrees
  EXPECT_TRUE(fs::exists(dir + "/t_ik_marker_errors.sto"));
  fs::remove_all(dir);
}

TEST(Cli, BadInputExitsWithFileLineAndField) {
  const std::string dir = cpgait::refdata::temp_dir("cli_bad");
  {
    std::FILE* f = std::fopen((dir + "/bad.trc").c_str(), "w");
    std::fputs("PathFileType\t4\nDataRate\tNumFrames\tNumMarkers\tUnits\n60\t1\t1\tfurlongs\nFrame#\tTime\tA\n\n1\t0\t1\t2\t3\n", f);
    std::fclose(f);
  }
  const CliRun r = run("ik --model " + cpgait::refdata::fixture("models/walker.osim") + " --markers " + dir + "/bad.trc -o " + dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("bad.trc:3: Units"), std::string::npos) << r.output;
  const CliRun t = run("run-tool " + cpgait::refdata::fixture("models/walker.osim"));
  EXPECT_EQ(t.status, 2);
  EXPECT_NE(t.output.find("not supported"), std::string::npos) << t.output;
  fs::remove_all(dir);
}

// Options or files given through a pipe (`--options <(echo ...)`, a FIFO) have no size to ask for:
// they are read to their end, and refused past the limit like a file, not as a file of 2^64 bytes.
TEST(Cli, FilesThroughAPipeAreRead) {
  const std::string dir = cpgait::refdata::temp_dir("cli_pipe");
  const std::string fifo = dir + "/options.json";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string text = std::string("{\"stages\": [\"ik\"]}\n") + std::string(100000, ' ');
  auto write_once = [&] {
    std::ofstream out(fifo, std::ios::binary);
    out << text;
  };
  std::thread writer(write_once);
  EXPECT_EQ(cpgait::text::read_file(fifo), text);
  writer.join();
  // Over the limit: 3000 bytes fit the pipe's buffer, so the writer is done before the reader gives up.
  std::thread again([&] {
    std::ofstream out(fifo, std::ios::binary);
    out << text.substr(0, 3000);
  });
  try {
    cpgait::text::read_file(fifo, 1000);
    ADD_FAILURE() << "a pipe over the limit was read";
  } catch (const cpgait::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("over the limit of 1000"), std::string::npos) << e.what();
  }
  again.join();
  fs::remove_all(dir);
}

// run-tool on OpenSim's IK setup writes OpenSim's IK result: every coordinate within 0.05 deg (or
// 0.05 mm) RMS of OutputReference's (measured in-process 0.0062 deg and 0.0023 mm at worst).
TEST(CliReference, RunToolRunsOpenSimsIkSetup) {
  const std::string setup = cpgait::refdata::gait2392("pipeline/subject01_Setup_IK.xml");
  const std::string reference = cpgait::refdata::gait2392("pipeline/OutputReference/subject01_walk1_ik.mot");
  for (const auto& p : {setup, reference, cpgait::refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim"),
                        cpgait::refdata::gait2392("pipeline/subject01_walk1.trc")})
    REQUIRE_REFERENCE(p);
  const std::string dir = cpgait::refdata::temp_dir("cli_runtool");
  const CliRun r = run("run-tool " + setup + " --results " + dir);
  ASSERT_EQ(r.status, 0) << r.output;
  const cpgait::Storage q = cpgait::read_storage(dir + "/subject01_walk1_ik.mot");
  EXPECT_EQ(q.num_rows(), 121);
  EXPECT_EQ(q.num_columns(), 24);
  const auto differences = cpgait::refdata::column_differences(q, cpgait::read_storage(reference));
  EXPECT_EQ(differences.size(), 23u);
  double worst_deg = 0;
  for (const auto& [name, d] : differences) {
    const bool translation = name.find("_t") == name.size() - 3;
    EXPECT_EQ(d.rows, 121) << name;
    EXPECT_LT(d.rms, translation ? 5e-5 : 0.05) << name << " (deg, or m for pelvis_tx/ty/tz)";
    if (!translation) worst_deg = std::max(worst_deg, d.rms);
  }
  std::printf("[ info ] run-tool IK vs OpenSim's: worst coordinate %.4f deg RMS\n", worst_deg);
  const cpgait::Storage e = cpgait::read_storage(dir + "/subject01_ik_marker_errors.sto");
  EXPECT_EQ(e.num_rows(), 121);
  fs::remove_all(dir);
}

TEST(CliReference, RunToolRunsOpenSimsCmcSetup) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  REQUIRE_REFERENCE(pl + "subject01_Setup_CMC.xml");
  const std::string dir = cpgait::refdata::temp_dir("cli_cmc");
  const CliRun r = run("run-tool " + pl + "subject01_Setup_CMC.xml --results " + dir);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("external forces: measured loads"), std::string::npos) << r.output;
  // The shipped model's muscles were not scaled with its bones: said, and fixed on request.
  EXPECT_NE(r.output.find("were their fibre and tendon lengths scaled"), std::string::npos) << r.output;
  const std::string generic = cpgait::refdata::gait2392("model/gait2392_simbody.osim");
  if (fs::exists(generic)) {
    const CliRun scaled = run("run-tool " + pl + "subject01_Setup_CMC.xml --scale-muscles-from " + generic + " --results " + dir + "/scaled");
    ASSERT_EQ(scaled.status, 0) << scaled.output;
    EXPECT_NE(scaled.output.find("92 muscles scaled"), std::string::npos) << scaled.output;
    EXPECT_EQ(scaled.output.find("were their fibre and tendon lengths scaled"), std::string::npos) << scaled.output;
  } else {
    std::printf("[ info ] not run: run-tool --scale-muscles-from (%s absent)\n", generic.c_str());
  }
  for (const char* f : {"_controls.sto", "_states.sto", "_Kinematics_q.sto", "_pErr.sto", "_Actuation_force.sto", "_avgResiduals.txt"})
    EXPECT_TRUE(fs::exists(dir + "/subject01_walk1" + f)) << f;
  const cpgait::Storage q = cpgait::read_storage(dir + "/subject01_walk1_Kinematics_q.sto");
  EXPECT_EQ(q.num_columns(), 24);
  EXPECT_NEAR(q.time()[0], 0.53, 1e-9);  // after OpenSim's 0.03 s settling
  EXPECT_NEAR(q.time()[q.num_rows() - 1], 1.99, 1e-6);  // the last full window before the data end
  const cpgait::Storage c = cpgait::read_storage(dir + "/subject01_walk1_controls.sto");
  EXPECT_GE(c.column("soleus_r.excitation"), 1);
  EXPECT_GE(c.column("FX.excitation"), 1);
  // Forward from CMC's controls and states (OpenSim's Forward tool), and OpenSim's own Forward setup,
  // whose states file is not shipped: refused with the field.
  const CliRun fw = run("forward --model " + pl + "OutputReference/subject01_simbody_adjusted.osim --actuators " + pl +
                        "gait2392_CMC_Actuators.xml --controls " + dir + "/subject01_walk1_controls.sto --states " + dir +
                        "/subject01_walk1_states.sto --loads " + pl + "subject01_walk1_grf.xml --time 0.8 0.85 -o " + dir + " --name fw");
  ASSERT_EQ(fw.status, 0) << fw.output;
  EXPECT_EQ(cpgait::read_storage(dir + "/fw_Kinematics_q.sto").num_rows(), 51);
  EXPECT_TRUE(fs::exists(dir + "/fw_Actuation_force.sto"));
  const CliRun fs_setup = run("run-tool " + pl + "subject01_Setup_Forward.xml --results " + dir);
  EXPECT_EQ(fs_setup.status, 2);
  EXPECT_NE(fs_setup.output.find("states_file"), std::string::npos) << fs_setup.output;
  // A task set naming a coordinate the model lacks: the file, line and field.
  std::ofstream(dir + "/tasks.xml") << "<OpenSimDocument><CMC_TaskSet><objects>\n<CMC_Joint name=\"x\">\n"
                                       "<coordinate>no_such</coordinate></CMC_Joint></objects></CMC_TaskSet></OpenSimDocument>";
  const CliRun bad = run("cmc --model " + pl + "OutputReference/subject01_simbody_adjusted.osim --kinematics " + pl +
                         "OutputReference/ResultsRRA/subject01_walk1_RRA_Kinematics_q.sto --tasks " + dir + "/tasks.xml -o " + dir);
  expect_refused(bad, 2, "tasks.xml:2");
  EXPECT_NE(bad.output.find("no_such"), std::string::npos) << bad.output;
  fs::remove_all(dir);
}

// id, so and run-tool from the command line, their files compared with OpenSim's: ID with the
// published ID output (each coordinate within 2 N m or 5 % of its peak, the reference test's target),
// SO on OpenSim 4.1's IK with OpenSim 4.1's activations (each active muscle within 0.03).
TEST(CliReference, IdAndSoFromTheCommandLine) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  const std::string published_id = pl + "OutputReference/ResultsInverseDynamics/InverseDynamicsOutput.sto";
  const std::string ik41 = cpgait::refdata::shared_path("opensim41-here/IK/subject01_walk1_ik.mot");
  const std::string so41 = cpgait::refdata::shared_path("opensim41-here/SO/subject01_walk1_StaticOptimization_activation.sto");
  for (const auto& p : {pl + "subject01_walk1_grf.mot", pl + "subject01_walk1_grf.xml", pl + "subject01_walk1_ik.mot",
                        pl + "OutputReference/subject01_simbody.osim", pl + "gait2392_SO_weak_Residual_Actuators.xml",
                        pl + "subject01_Setup_InverseDynamics.xml", pl + "setup_static_optimization.xml", published_id, ik41, so41})
    REQUIRE_REFERENCE(p);
  const std::string dir = cpgait::refdata::temp_dir("cli_idso");
  const std::string model = pl + "OutputReference/subject01_simbody.osim";
  CliRun id = run("id --model " + model + " --coordinates " + pl + "subject01_walk1_ik.mot --loads " + pl +
                  "subject01_walk1_grf.xml --cutoff 6 --time 0.5 1.0 -o " + dir + "/id.sto");
  ASSERT_EQ(id.status, 0) << id.output;
  const cpgait::Storage t = cpgait::read_storage(dir + "/id.sto");
  EXPECT_EQ(t.num_rows(), 31);
  EXPECT_GE(t.column("hip_flexion_r_moment"), 1);
  CliRun so = run("so --model " + model + " --coordinates " + pl + "subject01_walk1_ik.mot --loads " + pl +
                  "subject01_walk1_grf.xml --actuators " + pl + "gait2392_SO_weak_Residual_Actuators.xml --cutoff 6 --time 0.5 0.7 --name walk -o " + dir);
  ASSERT_EQ(so.status, 0) << so.output;
  const cpgait::Storage a = cpgait::read_storage(dir + "/walk_StaticOptimization_activation.sto");
  EXPECT_EQ(a.num_rows(), 13);
  EXPECT_EQ(a.num_columns(), 1 + 92 + 6);
  EXPECT_TRUE(fs::exists(dir + "/walk_StaticOptimization_force.sto"));
  // run-tool with OpenSim's ID setup writes where asked, named as the setup says.
  CliRun rt = run("run-tool " + pl + "subject01_Setup_InverseDynamics.xml --results " + dir);
  ASSERT_EQ(rt.status, 0) << rt.output;
  const auto id_differences = cpgait::refdata::column_differences(cpgait::read_storage(dir + "/InverseDynamicsOutput.sto"),
                                                                  cpgait::read_storage(published_id), 1e-4);
  EXPECT_EQ(id_differences.size(), 23u);
  double worst_id = 0;
  for (const auto& [name, d] : id_differences) {
    EXPECT_GT(d.rows, 50) << name;
    EXPECT_LT(d.rms, std::max(2.0, 0.05 * d.peak)) << name;
    worst_id = std::max(worst_id, d.rms);
  }
  std::printf("[ info ] run-tool ID vs OpenSim's published output: worst coordinate %.3f N m (or N) RMS\n", worst_id);
  // SO on OpenSim 4.1's IK (as OpenSim 4.1 ran it here), against its activations.
  CliRun so41_run = run("so --model " + model + " --coordinates " + ik41 + " --loads " + pl + "subject01_walk1_grf.xml --actuators " + pl +
                        "gait2392_SO_weak_Residual_Actuators.xml --cutoff 6 --name s41 -o " + dir);
  ASSERT_EQ(so41_run.status, 0) << so41_run.output;
  int active = 0;
  double worst_so = 0;
  // OpenSim 4.1 wrote its frames between the IK's (0.492, 0.508, ... s): ours are read between frames.
  for (const auto& [name, d] : cpgait::refdata::column_differences(cpgait::read_storage(dir + "/s41_StaticOptimization_activation.sto"),
                                                                     cpgait::read_storage(so41), 1e-6, true)) {
    if (d.peak <= 0.05 || name.size() < 3 || name[0] == 'F' || name[0] == 'M') continue;  // inactive, or a residual
    EXPECT_GT(d.rows, 80) << name;
    EXPECT_LT(d.rms, 0.03) << name;
    worst_so = std::max(worst_so, d.rms);
    ++active;
  }
  EXPECT_GE(active, 80);
  std::printf("[ info ] cpgait so vs OpenSim 4.1: %d active muscles, worst activation %.4f RMS (read between our frames)\n", active, worst_so);
  // The pipeline's old PrescribedForce loads are refused with the file and line.
  CliRun old = run("run-tool " + pl + "setup_static_optimization.xml --results " + dir);
  EXPECT_EQ(old.status, 2);
  EXPECT_NE(old.output.find("foot_floor_loads.xml:"), std::string::npos) << old.output;
  fs::remove_all(dir);
}

// The SO tutorial's setup names subject01_simbody_adjusted.osim, shipped as *_StaticOp.osim: as
// shipped it is refused naming model_file; with run-tool --model it runs, OpenSim's frames included
// (every 10th sample from 0.5 s and the final 1.999 s).
TEST(CliReference, RunToolModelOverrideRunsTheSoTutorial) {
  const std::string so = cpgait::refdata::gait2392("so_tutorial/");
  REQUIRE_REFERENCE(so + "subject01_walk1_grf.mot");
  const std::string dir = cpgait::refdata::temp_dir("cli_so_tutorial");
  const CliRun shipped = run("run-tool " + so + "setup_static_optimization.xml --results " + dir);
  EXPECT_EQ(shipped.status, 2);
  EXPECT_NE(shipped.output.find("model_file"), std::string::npos) << shipped.output;
  const CliRun missing = run("run-tool " + so + "setup_static_optimization.xml --model " + dir + "/none.osim --results " + dir);
  EXPECT_NE(missing.status, 0);
  const CliRun r = run("run-tool " + so + "setup_static_optimization.xml --model " + so + "subject01_simbody_adjusted_StaticOp.osim --results " + dir);
  ASSERT_EQ(r.status, 0) << r.output;
  const cpgait::Storage a = cpgait::read_storage(dir + "/subject01_StaticOptimization_activation.sto");
  ASSERT_EQ(a.num_rows(), 151);
  EXPECT_NEAR(a.time()[0], 0.5, 1e-9);
  EXPECT_NEAR(a.time()[149], 1.99, 1e-9);
  EXPECT_NEAR(a.time()[150], 1.999, 1e-9);
  EXPECT_EQ(a.num_columns(), 1 + 92 + 6);
  fs::remove_all(dir);
}

TEST(Cli, DetectCalibrateAndCaptureFromTheCommandLine) {
  const std::string dir = cpgait::refdata::temp_dir("cli_video");
  // detect: a rendered image with two tags; JSON with ids and four corners each.
  const cpgait::video::Camera cam = cpgait::fixtures::lab_rig()[0];
  std::vector<cv::Mat> textures{cpgait::fixtures::tag_texture("tag36h11", 3), cpgait::fixtures::tag_texture("tag36h11", 17)};
  std::vector<cpgait::fixtures::Quad> quads;
  for (int i = 0; i < 2; ++i) {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = cam.rotation_cam_from_world.transpose();
    X.translation() = cam.position_world_m() + X.linear() * Eigen::Vector3d(-0.3 + 0.6 * i, 0, 2.5);
    quads.push_back(cpgait::fixtures::tag_quad("tag36h11", 0.12, X, i));
  }
  std::mt19937 rng(1);
  cv::imwrite(dir + "/tags.png", cpgait::fixtures::ViewRenderer(cam, {}).render({quads}, textures, rng));
  const CliRun d = run("detect " + dir + "/tags.png");
  ASSERT_EQ(d.status, 0) << d.output;
  const auto j = nlohmann::json::parse(d.output);
  ASSERT_EQ(j.size(), 1u);
  std::set<int> ids;
  for (const auto& t : j[0]["detections"]) {
    ids.insert(t["id"].get<int>());
    EXPECT_EQ(t["corners_px"].size(), 4u);
  }
  EXPECT_EQ(ids, (std::set<int>{3, 17}));
  EXPECT_EQ(run("detect " + dir + "/missing.png").status, 2);
  // capture: a video for a camera the calibration does not have is refused, naming it.
  cpgait::video::write_calibration(cpgait::fixtures::lab_rig(), dir + "/cal.json");
  {
    std::ofstream(dir + "/tags.json") << cpgait::video::format_tag_set_json(cpgait::fixtures::tagged_walker().tags);
    std::ofstream(dir + "/side.avi") << "x";
  }
  const CliRun c = run("capture --videos " + dir + "/side.avi --calibration " + dir + "/cal.json --tags " + dir + "/tags.json -o " + dir + "/m.trc");
  EXPECT_EQ(c.status, 2);
  EXPECT_NE(c.output.find("no camera named 'side'"), std::string::npos) << c.output;
  // calibrate: a board file with a bad field is refused before any video is read.
  { std::ofstream(dir + "/board.json") << R"({"rows": 5, "cols": 6, "tag_size_m": 40})"; }
  const CliRun b = run("calibrate --board " + dir + "/board.json --videos " + dir + "/side.avi -o " + dir + "/c.json");
  EXPECT_EQ(b.status, 2);
  EXPECT_NE(b.output.find("tag_size_m"), std::string::npos) << b.output;
  fs::remove_all(dir);
}

TEST(Cli, CpgFitThenRun) {
  const std::string dir = cpgait::refdata::temp_dir("cli_cpg");
  // Three cycles of 1.0 s of two muscles' bursts, sampled at 100 Hz.
  std::vector<double> time;
  Eigen::MatrixXd v(301, 2);
  for (int i = 0; i <= 300; ++i) {
    const double t = i / 100.0, ph = t - std::floor(t);
    time.push_back(t);
    v(i, 0) = 0.5 * std::exp(-0.5 * std::pow((ph - 0.3) / 0.06, 2));
    v(i, 1) = 0.3 + 0.3 * std::sin(2 * M_PI * ph);
  }
  cpgait::write_storage(cpgait::make_storage("patterns", {"a", "b"}, time, v, false), dir + "/p.sto");
  const CliRun f = run("cpg fit --patterns " + dir + "/p.sto --cycle-starts 0 1 2 3 -o " + dir + "/cpg.json");
  ASSERT_EQ(f.status, 0) << f.output;
  EXPECT_NE(f.output.find("3 gait cycle(s), mean 1.000 s"), std::string::npos) << f.output;
  EXPECT_TRUE(fs::exists(dir + "/cpg_fitted.sto"));
  const CliRun r = run("cpg run --model " + dir + "/cpg.json --duration 2 --dt 0.002 --speed 1.25 -o " + dir + "/run");
  ASSERT_EQ(r.status, 0) << r.output;
  const cpgait::Storage e = cpgait::read_storage(dir + "/run_excitations.sto");
  EXPECT_EQ(e.num_rows(), 1000);
  EXPECT_EQ(e.labels, (std::vector<std::string>{"time", "a", "b"}));
  EXPECT_NE(r.output.find("cycle 0.800 s"), std::string::npos) << r.output;
  EXPECT_EQ(run("cpg fit --patterns " + dir + "/p.sto -o " + dir + "/x.json").status, 2);  // no cycles given
  fs::remove_all(dir);
}

// A stored controller replays the stage's walks from the files the stage wrote: the CPG's JSON and the
// reference it walked against (_gait_reference.sto, every digit) to the bit; the IK's .mot (12 digits,
// degrees) as closely as its digits allow. The trial's times are rounded to the millisecond, as
// subject01's TRC holds them (60 Hz: 0.017, 0.033), so the IK's samples are unevenly spaced and the
// trajectories resampled. Before, `cpgait gait` fitted the feet to those resampled trajectories and
// the stage to the recorded poses: on subject01 the belts differed by 2e-5, and a replay of seed 1's
// knob 0.8 fell at 9.73 s where the stage's walk lasted 10 s. The stage simulates off the defaults
// (its controller every 4 ms, tolerance 2e-3): the controller records that simulation and a replay
// runs in it unless told otherwise.
TEST(Cli, TheGaitStagesWalksReplayFromItsFiles) {
  const std::string dir = cpgait::refdata::temp_dir("cli_replay_bits");
  const std::string model = cpgait::refdata::fixture("models/walker.osim");
  ASSERT_EQ(run("synth --model " + model + " --duration 3 --rate 60 -o " + dir + "/w.trc").status, 0);
  {
    std::istringstream in(cpgait::text::read_file(dir + "/w.trc"));
    std::string rounded, line;
    for (int n = 1; std::getline(in, line); ++n) {
      const auto a = line.find('\t'), b = a == std::string::npos ? a : line.find('\t', a + 1);
      if (n > 5 && b != std::string::npos) {  // a frame: number, time, markers
        char t[32];
        std::snprintf(t, sizeof t, "%.3f", std::stod(line.substr(a + 1, b - a - 1)));
        line = line.substr(0, a + 1) + t + line.substr(b);
      }
      rounded += line + "\n";
    }
    std::ofstream(dir + "/w.trc") << rounded;
  }
  std::ofstream(dir + "/options.json") << R"({"gait": {"tune_evaluations": 4, "tune_horizon_s": 1.0, "speed_knobs": [0.8], "schedule_evaluations": 0,
                                              "check_tolerances": [], "foot_spheres": 2, "control_interval_s": 0.004, "tolerance": 0.002}})";
  const CliRun r = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/options.json -o " + dir + "/out");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(cpgait::text::read_file(dir + "/out/w_ik.mot").find("\n0.017\t"), std::string::npos);  // times as rounded
  auto replay = [&](const std::string& kinematics, const std::string& knob, const std::string& out) {
    const CliRun g = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir + "/out/" + kinematics +
                         " --duration 10 --speed " + knob + " -o " + dir + "/" + out);
    EXPECT_EQ(g.status, 0) << g.output;
    return cpgait::text::read_file(dir + "/" + out + "_gait.mot");
  };
  for (const std::string knob : {"1", "0.8"}) {
    const std::string staged = cpgait::text::read_file(dir + (knob == "1" ? "/out/w_gait.mot" : "/out/w_gait_speed_0.8.mot"));
    ASSERT_GT(std::count(staged.begin(), staged.end(), '\n'), 50) << "knob " << knob;
    EXPECT_TRUE(staged == replay("w_gait_reference.sto", knob, "exact" + knob)) << "knob " << knob;
    // From the .mot: its 12 digits apart, the same walk (as printed) over its first second.
    replay("w_ik.mot", knob, "mot" + knob);
    const cpgait::Storage a = cpgait::read_storage(dir + (knob == "1" ? "/out/w_gait.mot" : "/out/w_gait_speed_0.8.mot")),
                          b = cpgait::read_storage(dir + "/mot" + knob + "_gait.mot");
    const int rows = std::min({a.num_rows(), b.num_rows(), 250});
    ASSERT_GT(rows, 50);
    EXPECT_LT((a.data.topRows(rows) - b.data.topRows(rows)).cwiseAbs().maxCoeff(), 1e-6) << "knob " << knob;
  }
  EXPECT_TRUE(cpgait::text::read_file(dir + "/out/w_gait_contact_forces.sto") == cpgait::text::read_file(dir + "/exact1_gait_contact_forces.sto"));
  const nlohmann::json tuned = nlohmann::json::parse(cpgait::text::read_file(dir + "/out/w_cpg_tuned.json"));
  EXPECT_EQ(tuned["controller"]["simulation"], nlohmann::json({{"control_interval_s", 0.004}, {"integrator", "ros34pw2"}, {"tolerance", 0.002}}));
  // Told otherwise: the controller every 2.5 ms, another walk.
  const CliRun told = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                          "/out/w_gait_reference.sto --duration 10 --control-interval 0.0025 -o " + dir + "/told");
  ASSERT_EQ(told.status, 0) << told.output;
  EXPECT_NE(told.output.find("updated every 2.5 ms, ros34pw2 at tolerance 0.002"), std::string::npos) << told.output;
  EXPECT_FALSE(cpgait::text::read_file(dir + "/out/w_gait.mot") == cpgait::text::read_file(dir + "/told_gait.mot"));
  fs::remove_all(dir);
}

// The gait stage's tuning (issue 22) through the pipeline: the tuned CPG, its controller in the JSON,
// is written beside the gait, whose summary reports the tuning and walks without residuals; `cpgait
// gait` replays the tuned CPG's controller. (The walker's synthetic trial is no gait to tune well:
// this checks the plumbing; subject01's tuning is checked in test_so_gait2392.cpp.)
TEST(Cli, GaitStageTunesAndTheTunedCpgReplays) {
  const std::string dir = cpgait::refdata::temp_dir("cli_tune");
  const std::string model = cpgait::refdata::fixture("models/walker.osim");
  ASSERT_EQ(run("synth --model " + model + " --duration 4 -o " + dir + "/w.trc").status, 0);
  std::ofstream(dir + "/options.json")
      << R"({"gait": {"tune_evaluations": 8, "tune_horizon_s": 1.0, "tune_rotation_limit_deg": 0.01, "speed_knobs": [0.8], "schedule_evaluations": 4,
             "foot_spheres": 2, "gain_margin": 0.8}})";
  const CliRun r = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/options.json -o " + dir + "/out");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json gait = nlohmann::json::parse(cpgait::text::read_file(dir + "/out/w_gait.json"));
  ASSERT_TRUE(gait.contains("tuning")) << gait.dump();
  EXPECT_GE(gait["tuning"]["simulations"].get<int>(), 8);
  // What the tuning simulated: each simulation a level walk, no longer than the 1 s horizon, and a
  // walk -> stand trial (the default tune_stop_at, 0.45) that goes on from the level walk's state at
  // the stop: 0.55 s at most.
  const double simulated_s = gait["tuning"]["simulated_s"].get<double>();
  EXPECT_GT(simulated_s, 0.0);
  EXPECT_LE(simulated_s, 1.55 * gait["tuning"]["simulations"].get<int>() + 1e-9);
  EXPECT_EQ(gait["tuning"]["budget_simulated_s"].get<double>(), 0.0);
  // The rotation bound reaches the tuner: 0.01 deg, far below any walk's tracking, costs each candidate
  // fall_weight (10) per bound's worth of excess, where without it a candidate costs at most ~12.
  EXPECT_EQ(gait["tuning"]["rotation_limit_deg"].get<double>(), 0.01);
  EXPECT_GT(gait["tuning"]["cost"][0].get<double>(), 100.0) << gait["tuning"].dump();
  EXPECT_FALSE(gait["pelvis_residuals"].get<bool>());
  // On its own it walks (or tries to) the trial's length and at least 10 s: the walker falls sooner.
  EXPECT_TRUE(gait["simulated_s"].get<double>() >= 10.0 - 1e-9 || !gait["fell_at_s"].is_null()) << gait.dump();
  // A fall, the walk's or a speed knob's, is also said among the warnings, with its time; a walk that
  // did not fall is not.
  const std::string warnings = gait["warnings"].dump();
  auto fall_said = [&](const nlohmann::json& walk, const std::string& which) {
    if (walk["fell_at_s"].is_null()) return warnings.find(which + " fell at ") == std::string::npos;
    char said[160];
    std::snprintf(said, sizeof said, "%s fell at %g s of 10 s (the pelvis below 75 %% of its starting height)", which.c_str(), walk["fell_at_s"].get<double>());
    return warnings.find(said) != std::string::npos;
  };
  EXPECT_TRUE(fall_said(gait, "the walk")) << gait["fell_at_s"] << warnings;
  ASSERT_EQ(gait["speed_knobs"].size(), 1u);
  EXPECT_TRUE(fall_said(gait["speed_knobs"][0], "the walk at speed knob 0.8")) << gait["speed_knobs"][0]["fell_at_s"] << warnings;
  // Tuned to walk 1 s of those 10: the summary says so.
  EXPECT_EQ(gait["tuning"]["horizon_s"].get<double>(), 1.0);
  EXPECT_NE(gait["warnings"].dump().find("tuned to walk 1 s (tune_horizon_s) and the walks last 10 s"), std::string::npos) << gait["warnings"];
  // Without residuals the walk is taken again at the default check tolerances; each is the walk the
  // CLI replays at that tolerance (as long, falling at the same time).
  ASSERT_EQ(gait["tolerance_check"].size(), 2u) << gait.dump();
  EXPECT_EQ(gait["tolerance_check"][0]["tolerance"].get<double>(), 5e-4);
  EXPECT_EQ(gait["tolerance_check"][1]["tolerance"].get<double>(), 2e-3);
  const nlohmann::json& coarse = gait["tolerance_check"][1];
  EXPECT_GT(coarse["simulated_s"].get<double>(), 0.1) << coarse.dump();
  const CliRun replay_coarse = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                                   "/out/w_ik.mot --duration 10 --tolerance 2e-3 -o " + dir + "/coarse");
  ASSERT_EQ(replay_coarse.status, 0) << replay_coarse.output;
  const nlohmann::json replayed_coarse = nlohmann::json::parse(cpgait::text::read_file(dir + "/coarse_gait.json"));
  EXPECT_NEAR(replayed_coarse["simulated_s"].get<double>(), coarse["simulated_s"].get<double>(), 1e-9);
  EXPECT_EQ(replayed_coarse["fell_at_s"], coarse["fell_at_s"]);
  // "gain_margin": each walk again with each feedback gain scaled by 0.8 and 1.25, in the summary; the
  // main walk's 16 are those of the CLI's replay with --gain-margin 0.8.
  ASSERT_TRUE(gait.contains("gain_margin")) << gait.dump();
  ASSERT_EQ(gait["gain_margin"]["walks"].size(), 16u);
  ASSERT_EQ(gait["speed_knobs"][0]["gain_margin"]["walks"].size(), 16u) << gait["speed_knobs"].dump();
  const CliRun replay_margin = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                                   "/out/w_ik.mot --duration 10 --gain-margin 0.8 -o " + dir + "/stage_margin");
  ASSERT_EQ(replay_margin.status, 0) << replay_margin.output;
  const nlohmann::json replayed_margin = nlohmann::json::parse(cpgait::text::read_file(dir + "/stage_margin_gait.json"))["gain_margin"];
  EXPECT_EQ(replayed_margin["still_walking"], gait["gain_margin"]["still_walking"]);
  for (std::size_t i = 0; i < 16; ++i)
    EXPECT_NEAR(replayed_margin["walks"][i]["walked_s"].get<double>(), gait["gain_margin"]["walks"][i]["walked_s"].get<double>(), 1e-9) << i;
  const nlohmann::json tuned = nlohmann::json::parse(cpgait::text::read_file(dir + "/out/w_cpg_tuned.json"));
  ASSERT_TRUE(tuned.contains("controller"));
  EXPECT_EQ(tuned["controller"]["reflex_kp"].get<double>(), gait["tuning"]["controller"]["reflex_kp"].get<double>());
  // schedule_evaluations: a controller tuned again at knob 0.8, stored beside the one at knob 1.
  ASSERT_EQ(tuned["controller_schedule"].size(), 1u) << tuned.dump();
  EXPECT_EQ(tuned["controller_schedule"][0]["speed"].get<double>(), 0.8);
  ASSERT_EQ(gait["tuning"]["schedule"].size(), 1u);
  EXPECT_GE(gait["tuning"]["schedule"][0]["simulations"].get<int>(), 4);
  const CliRun replay = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                            "/out/w_ik.mot --duration 0.5 -o " + dir + "/replay");
  ASSERT_EQ(replay.status, 0) << replay.output;
  EXPECT_NE(replay.output.find("controller from the CPG"), std::string::npos) << replay.output;
  EXPECT_NE(replay.output.find("without residuals"), std::string::npos) << replay.output;
  // --gain-margin: the replay again with each feedback gain at 0.8 and 1.25 times, 16 walks in _gait.json.
  const CliRun margin = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                            "/out/w_ik.mot --duration 0.5 --gain-margin 0.8 -o " + dir + "/margin");
  ASSERT_EQ(margin.status, 0) << margin.output;
  EXPECT_NE(margin.output.find("gain margin: "), std::string::npos) << margin.output;
  const nlohmann::json gm = nlohmann::json::parse(cpgait::text::read_file(dir + "/margin_gait.json"))["gain_margin"];
  ASSERT_EQ(gm["walks"].size(), 16u) << gm.dump();
  EXPECT_EQ(gm["factor"].get<double>(), 0.8);
  EXPECT_EQ(gm["walks"][0]["gain"], "reflex_kp");
  EXPECT_EQ(gm["walks"][1]["scale"].get<double>(), 1.25);
  int still = 0;
  for (const nlohmann::json& w : gm["walks"]) {
    still += !w["fell"].get<bool>();
    EXPECT_LE(w["walked_s"].get<double>(), 0.5 + 1e-12);
  }
  EXPECT_EQ(gm["still_walking"].get<int>(), still);
  EXPECT_NE(run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                "/out/w_ik.mot --duration 0.5 --gain-margin 1.5 -o " + dir + "/margin").status, 0);
  // Feet from a file: without a ground of its own it gets the default feet's, placed under the recorded
  // feet (on the walker's treadmill-free trial: still) with the spheres fitted; with one, the file's.
  const std::string spheres = R"("spheres": [{"name": "heel_r", "body": "foot_r", "location_m": [0, -0.04, 0]}, {"name": "heel_l", "body": "foot_l", "location_m": [0, -0.04, 0]}], "defaults": {"radius_m": 0.03})";
  std::ofstream(dir + "/feet.json") << "{" + spheres + "}";
  std::ofstream(dir + "/feet_on_ground.json") << R"({"ground_height_m": -0.5, )" + spheres + "}";
  const CliRun own_feet = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                              "/out/w_ik.mot --duration 0.2 --contacts " + dir + "/feet.json -o " + dir + "/own_feet");
  ASSERT_EQ(own_feet.status, 0) << own_feet.output;
  EXPECT_NE(own_feet.output.find("ground under the recorded feet"), std::string::npos) << own_feet.output;
  EXPECT_NE(own_feet.output.find("feet fitted to the trial"), std::string::npos) << own_feet.output;
  const CliRun given_ground = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                                  "/out/w_ik.mot --duration 0.2 --contacts " + dir + "/feet_on_ground.json -o " + dir + "/given_ground");
  ASSERT_EQ(given_ground.status, 0) << given_ground.output;
  EXPECT_EQ(given_ground.output.find("ground under the recorded feet"), std::string::npos) << given_ground.output;
  // The file's ground half a metre below the feet: no sphere touches it; under the feet, they carry the walker.
  const cpgait::Storage in_air = cpgait::read_storage(dir + "/given_ground_gait_contact_forces.sto"),
                        standing = cpgait::read_storage(dir + "/own_feet_gait_contact_forces.sto");
  EXPECT_LT(in_air.data.rightCols(in_air.data.cols() - 1).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_GT(standing.data.rightCols(standing.data.cols() - 1).cwiseAbs().maxCoeff(), 100.0);
  // From the heel strike and the beginning the tuning used (stored with the controller), the same walk
  // as the stage's, though the stage's is longer than the tuning's horizon and the replay shorter.
  EXPECT_NE(replay.output.find("the CPG's controller was tuned from"), std::string::npos) << replay.output;
  const cpgait::Storage staged = cpgait::read_storage(dir + "/out/w_gait.mot"), replayed = cpgait::read_storage(dir + "/replay_gait.mot");
  ASSERT_GE(staged.num_rows(), replayed.num_rows());
  ASSERT_GT(replayed.num_rows(), 100);
  EXPECT_LT((staged.data.topRows(replayed.num_rows()) - replayed.data).cwiseAbs().maxCoeff(), 1e-6);  // as printed
  // The stage's walk at speed knob 0.8 is the replay's at that knob, its stride compared with the
  // cycle / 0.8.
  ASSERT_EQ(gait["speed_knobs"].size(), 1u) << gait.dump();
  const nlohmann::json& slow = gait["speed_knobs"][0];
  EXPECT_EQ(slow["speed_knob"].get<double>(), 0.8);
  EXPECT_NEAR(slow["cycle_over_speed_s"].get<double>(), gait["cycle_over_speed_s"].get<double>() / 0.8, 1e-9);
  EXPECT_EQ(slow["file"].get<std::string>(), "w_gait_speed_0.8.mot");
  const CliRun replay_slow = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                                 "/out/w_ik.mot --duration 0.5 --speed 0.8 -o " + dir + "/slow");
  ASSERT_EQ(replay_slow.status, 0) << replay_slow.output;
  const cpgait::Storage staged_slow = cpgait::read_storage(dir + "/out/w_gait_speed_0.8.mot"), replayed_slow = cpgait::read_storage(dir + "/slow_gait.mot");
  ASSERT_GE(staged_slow.num_rows(), replayed_slow.num_rows());
  EXPECT_LT((staged_slow.data.topRows(replayed_slow.num_rows()) - replayed_slow.data).cwiseAbs().maxCoeff(), 1e-6);
  // Tuned again at knob 0.8 (over a ground step and through a push too, the worst rotation bounded),
  // the CPG keeps its controller and its schedule entry there is replaced.
  const CliRun retune = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                            "/out/w_ik.mot --duration 0.5 --speed 0.8 --tune 4 --tune-horizon 0.5 --tune-steps -0.01 --tune-pushes 0 0 -1 --tune-step-at 0.4 0.6 --tune-tolerances 2e-3 --tune-rotation-limit 5 -o " +
                            dir + "/k08");
  ASSERT_EQ(retune.status, 0) << retune.output;
  const nlohmann::json scheduled = nlohmann::json::parse(cpgait::text::read_file(dir + "/k08_cpg_tuned.json"));
  EXPECT_EQ(scheduled["controller"], tuned["controller"]);
  ASSERT_EQ(scheduled["controller_schedule"].size(), 1u);
  EXPECT_EQ(scheduled["controller_schedule"][0]["speed"].get<double>(), 0.8);
  // Feet: the stage's two per foot (its option; the default is five) are recorded with its controller; tuned on five, the controller
  // records five, and a replay stands on five unless told otherwise.
  EXPECT_EQ(tuned["controller"]["foot_spheres"].get<int>(), 2);
  const CliRun five = run("gait --model " + model + " --cpg " + dir + "/out/w_cpg_tuned.json --kinematics " + dir +
                          "/out/w_ik.mot --duration 0.6 --foot-spheres 5 --tune 2 --tune-horizon 0.5 --tune-ankle -o " + dir + "/k5");
  ASSERT_EQ(five.status, 0) << five.output;
  // The walker's ankles are pins across the way: asked to search the ankle strategy, the CLI says it did not.
  EXPECT_NE(five.output.find("--tune-ankle: the model has no rotation below each hip"), std::string::npos) << five.output;
  EXPECT_EQ(retune.output.find("--tune-ankle"), std::string::npos) << retune.output;
  // Walked longer than it was tuned to walk: a warning (none where the two are alike, above).
  EXPECT_NE(five.output.find("tuned to walk 0.5 s (--tune-horizon) and walking 0.6 s (--duration)"), std::string::npos) << five.output;
  EXPECT_EQ(retune.output.find("--tune-horizon"), std::string::npos) << retune.output;
  EXPECT_EQ(nlohmann::json::parse(cpgait::text::read_file(dir + "/k5_cpg_tuned.json"))["controller"]["foot_spheres"].get<int>(), 5);
  const CliRun on_five = run("gait --model " + model + " --cpg " + dir + "/k5_cpg_tuned.json --kinematics " + dir + "/out/w_ik.mot --duration 0.2 -o " + dir + "/on5");
  const CliRun on_two = run("gait --model " + model + " --cpg " + dir + "/k5_cpg_tuned.json --kinematics " + dir +
                            "/out/w_ik.mot --duration 0.2 --foot-spheres 2 -o " + dir + "/on2");
  ASSERT_EQ(on_five.status, 0) << on_five.output;
  ASSERT_EQ(on_two.status, 0) << on_two.output;
  EXPECT_EQ(cpgait::read_storage(dir + "/on5_gait_contact_forces.sto").num_columns(), 1 + 3 * 10);
  EXPECT_EQ(cpgait::read_storage(dir + "/on2_gait_contact_forces.sto").num_columns(), 1 + 3 * 4);
  // Tuned on a contact file, it needs the file again.
  nlohmann::json on_file = nlohmann::json::parse(cpgait::text::read_file(dir + "/k5_cpg_tuned.json"));
  on_file["controller"]["foot_spheres"] = 0;
  std::ofstream(dir + "/on_file_cpg.json") << on_file.dump();
  const CliRun no_file = run("gait --model " + model + " --cpg " + dir + "/on_file_cpg.json --kinematics " + dir + "/out/w_ik.mot --duration 0.2 -o " + dir + "/nofile");
  expect_refused(no_file, 2, "controller.foot_spheres");
  const CliRun on_three = run("gait --model " + model + " --cpg " + dir + "/k5_cpg_tuned.json --kinematics " + dir +
                              "/out/w_ik.mot --duration 0.2 --foot-spheres 3 -o " + dir + "/on3");
  expect_refused(on_three, 105, "--foot-spheres");  // CLI11's validation error
  const CliRun bad_push = run("gait --model " + model + " --cpg " + dir + "/k08_cpg_tuned.json --kinematics " + dir +
                              "/out/w_ik.mot --duration 0.5 --tune 2 --tune-pushes 0 0 -o " + dir + "/bad");
  expect_refused(bad_push, 2, "three numbers (x y z) per push");
  // The stage's ground steps, pushes and tolerances reach the tuner: each candidate's cost is the mean
  // over its walks, so the start's cost changes; a push needs three numbers, a tolerance is positive.
  std::ofstream(dir + "/perturbed.json")
      << R"({"gait": {"tune_evaluations": 8, "tune_horizon_s": 1.0, "tune_rotation_limit_deg": 0.01, "tune_steps_m": [-0.2], "tune_pushes_N_s": [0, 0, -30], "tune_tolerances": [1e-3, 1e-2], "tune_step_at": [0.3, 0.7], "tune_stop_at": [0.5], "control_interval_s": 0.001, "tolerance": 8e-3, "integrator": "rosenbrock", "tune_entrainment": true, "tune_swing_world": true, "tune_stance_hold": true, "tune_ankle": true, "speed_knobs": []}})";
  const CliRun perturbed = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/perturbed.json -o " + dir + "/perturbed");
  ASSERT_EQ(perturbed.status, 0) << perturbed.output;
  const nlohmann::json p = nlohmann::json::parse(cpgait::text::read_file(dir + "/perturbed/w_gait.json"));
  EXPECT_EQ(p["tuning"]["steps_m"], nlohmann::json::array({-0.2}));
  EXPECT_EQ(p["tuning"]["pushes_N_s"], nlohmann::json::array({0, 0, -30}));
  EXPECT_EQ(p["tuning"]["tolerances"], nlohmann::json::array({1e-3, 1e-2}));
  EXPECT_EQ(p["tuning"]["step_at"], nlohmann::json::array({0.3, 0.7}));
  EXPECT_EQ(p["tuning"]["stop_at"], nlohmann::json::array({0.5}));
  // The entrainment was searched: the tuned controller's share and phases moved off the untuned 0, 0, 0.5.
  EXPECT_EQ(p["tuning"]["entrainment"], true);
  const nlohmann::json searched = p["tuning"]["controller"]["entrainment"];
  EXPECT_NE(searched, nlohmann::json({{"share", 0.0}, {"phase_r", 0.0}, {"phase_l", 0.5}})) << searched.dump();
  EXPECT_FALSE(gait["tuning"]["entrainment"].get<bool>());
  // So were the swing hip's world share (from 1, SIMBICON's, for a CPG without a controller) and the stance hold (from 0).
  // The ankle strategy was asked for, but the walker's ankles only flex: it reports it unsearched, its gains 0.
  EXPECT_EQ(p["tuning"]["swing_world"], true);
  EXPECT_EQ(p["tuning"]["stance_hold"], true);
  EXPECT_NE(p["tuning"]["controller"]["swing_world"].get<double>(), 1.0);
  EXPECT_NE(p["tuning"]["controller"]["stance_hold"]["lateral_d"].get<double>(), 0.0);
  EXPECT_EQ(p["tuning"]["ankle"], false);
  EXPECT_EQ(p["tuning"]["controller"]["ankle_strategy"]["lateral_d_rad_per_m"].get<double>(), 0.0);
  EXPECT_EQ(gait["tuning"]["controller"]["ankle_strategy"]["lateral_d_rad_per_m"].get<double>(), 0.0);
  EXPECT_FALSE(gait["tuning"]["swing_world"].get<bool>());
  EXPECT_EQ(gait["tuning"]["controller"]["swing_world"].get<double>(), 0.0);
  // The walk's tolerance, controller interval and integrator: the defaults recorded, or the options',
  // which the CLI replays alike (the motion sampled at the interval).
  EXPECT_EQ(gait["tolerance"].get<double>(), 1e-3);
  EXPECT_EQ(gait["control_interval_s"].get<double>(), 0.0025);
  EXPECT_EQ(gait["integrator"], "ros34pw2");
  EXPECT_EQ(p["tolerance"].get<double>(), 8e-3);
  EXPECT_EQ(p["control_interval_s"].get<double>(), 0.001);
  EXPECT_EQ(p["integrator"], "rosenbrock");
  const CliRun replay_fast = run("gait --model " + model + " --cpg " + dir + "/perturbed/w_cpg_tuned.json --kinematics " + dir +
                                 "/perturbed/w_ik.mot --duration 0.5 --control-interval 0.001 --tolerance 8e-3 --integrator rosenbrock -o " + dir + "/fast");
  ASSERT_EQ(replay_fast.status, 0) << replay_fast.output;
  const cpgait::Storage staged_fast = cpgait::read_storage(dir + "/perturbed/w_gait.mot"), replayed_fast = cpgait::read_storage(dir + "/fast_gait.mot");
  ASSERT_GT(replayed_fast.num_rows(), 10);  // the walker, tuned on 8 simulations, may fall
  EXPECT_NEAR(replayed_fast.time()(1) - replayed_fast.time()(0), 0.001, 1e-9);
  ASSERT_GE(staged_fast.num_rows(), replayed_fast.num_rows());
  EXPECT_LT((staged_fast.data.topRows(replayed_fast.num_rows()) - replayed_fast.data).cwiseAbs().maxCoeff(), 1e-6);
  std::ofstream(dir + "/bad_interval.json") << R"({"gait": {"control_interval_s": 0.02}})";
  const CliRun bad_interval = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/bad_interval.json -o " + dir + "/bad_interval");
  expect_refused(bad_interval, 2, "gait.control_interval_s");
  std::ofstream(dir + "/bad_integrator.json") << R"({"gait": {"integrator": "euler"}})";
  const CliRun bad_integrator = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/bad_integrator.json -o " + dir + "/bad_integrator");
  expect_refused(bad_integrator, 2, "gait.integrator");
  const CliRun euler = run("gait --model " + model + " --cpg " + dir + "/perturbed/w_cpg_tuned.json --kinematics " + dir +
                           "/perturbed/w_ik.mot --duration 0.5 --integrator euler -o " + dir + "/euler");
  expect_refused(euler, 105, "--integrator");  // CLI11's validation error
  const CliRun slow_control = run("gait --model " + model + " --cpg " + dir + "/perturbed/w_cpg_tuned.json --kinematics " + dir +
                                  "/perturbed/w_ik.mot --duration 0.5 --control-interval 0.05 -o " + dir + "/slow_control");
  expect_refused(slow_control, 105, "--control-interval");  // CLI11's validation error
  // --entrainment and --entrainment-phases reach the walk (recorded in _gait.json), a share above 1 is refused.
  const CliRun entrained = run("gait --model " + model + " --cpg " + dir + "/perturbed/w_cpg_tuned.json --kinematics " + dir +
                               "/perturbed/w_ik.mot --duration 0.5 --entrainment 0.5 --entrainment-phases 0.1 0.6 -o " + dir + "/entrained");
  ASSERT_EQ(entrained.status, 0) << entrained.output;
  const nlohmann::json e = nlohmann::json::parse(cpgait::text::read_file(dir + "/entrained_gait.json"));
  EXPECT_EQ(e["entrainment"]["share"].get<double>(), 0.5) << e.dump();
  EXPECT_EQ(e["entrainment"]["phase_r"].get<double>(), 0.1);
  EXPECT_EQ(e["entrainment"]["phase_l"].get<double>(), 0.6);
  const CliRun over = run("gait --model " + model + " --cpg " + dir + "/perturbed/w_cpg_tuned.json --kinematics " + dir +
                          "/perturbed/w_ik.mot --duration 0.5 --entrainment 2 -o " + dir + "/over");
  expect_refused(over, 105, "--entrainment");
  EXPECT_GT(std::abs(p["tuning"]["cost"][0].get<double>() - gait["tuning"]["cost"][0].get<double>()), 1e-6) << p["tuning"].dump();
  std::ofstream(dir + "/bad_push.json") << R"({"gait": {"tune_evaluations": 8, "tune_pushes_N_s": [0, 0]}})";
  const CliRun bad_stage_push = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/bad_push.json -o " + dir + "/bad_stage");
  expect_refused(bad_stage_push, 2, "gait.tune_pushes_N_s");
  EXPECT_NE(bad_stage_push.output.find("a multiple of 3 numbers"), std::string::npos) << bad_stage_push.output;
  std::ofstream(dir + "/bad_tolerance.json") << R"({"gait": {"tune_evaluations": 8, "tune_tolerances": [0]}})";
  const CliRun bad_tolerance = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/bad_tolerance.json -o " + dir + "/bad_tol");
  expect_refused(bad_tolerance, 2, "gait.tune_tolerances");
  std::ofstream(dir + "/bad_check.json") << R"({"gait": {"residuals": false, "check_tolerances": [1e-3, -1]}})";
  const CliRun bad_check = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/bad_check.json -o " + dir + "/bad_check");
  expect_refused(bad_check, 2, "gait.check_tolerances");
  std::ofstream(dir + "/bad_feet.json") << R"({"gait": {"foot_spheres": 3}})";
  const CliRun bad_feet = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/bad_feet.json -o " + dir + "/bad_feet");
  expect_refused(bad_feet, 2, "gait.foot_spheres");
  std::ofstream(dir + "/bad_videos.json") << R"({"inputs": {"videos": ["cam0=a.mp4", 1]}})";
  const CliRun bad_videos = run("run --model " + model + " --options " + dir + "/bad_videos.json -o " + dir + "/bad_videos");
  expect_refused(bad_videos, 2, "inputs.videos");
  fs::remove_all(dir);
}

// Without tune_horizon_s the stage tunes its controller to walk as long as its walks last: a tuned
// controller walks its horizon, not necessarily beyond (tuned to 10 s, subject01's fell 0.3-17 s
// after it: docs/gait-tuning.md). The drift's weight reaches the tuning.
TEST(Cli, GaitStageTunesToTheWalksLengthByDefault) {
  const std::string dir = cpgait::refdata::temp_dir("cli_tune_horizon");
  const std::string model = cpgait::refdata::fixture("models/walker.osim");
  ASSERT_EQ(run("synth --model " + model + " --duration 2 -o " + dir + "/w.trc").status, 0);
  std::ofstream(dir + "/options.json") << R"({"gait": {"tune_evaluations": 4, "duration_s": 0.6, "speed_knobs": [], "check_tolerances": [],
                                              "foot_spheres": 2, "tune_drift_weight": 2}})";
  const CliRun r = run("run --model " + model + " --markers " + dir + "/w.trc --options " + dir + "/options.json -o " + dir + "/out");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json gait = nlohmann::json::parse(cpgait::text::read_file(dir + "/out/w_gait.json"));
  EXPECT_EQ(gait["tuning"]["horizon_s"].get<double>(), 0.6) << gait["tuning"].dump();
  // The drift's weight reaches the tuning; the walk, shorter than two of the walker's cycles, has none.
  EXPECT_EQ(gait["tuning"]["drift_weight"].get<double>(), 2.0);
  EXPECT_EQ(gait["drift_rad"].get<double>(), 0.0);
  EXPECT_EQ(gait["warnings"].dump().find("tune_horizon_s"), std::string::npos) << gait["warnings"];
  fs::remove_all(dir);
}

// A trial exported as a Z-up lab's C3D runs through IK as its TRC does (the markers turned into
// OpenSim's Y-up frame), and `cpgait convert` writes that TRC.
TEST(Cli, IkTakesC3dAsItTakesTrcAndConvertWritesTheTrc) {
  const std::string dir = cpgait::refdata::temp_dir("cli_c3d");
  cpgait::fixtures::SyntheticTrialOptions so;
  so.duration_s = 1.0;
  so.gap_fraction = 0.1;
  const cpgait::MarkerTrial trial = cpgait::fixtures::synthesize_trial(cpgait::refdata::walker(), so).markers;
  std::ofstream(dir + "/walk.trc") << cpgait::format_trc(trial, "mm");
  std::ofstream(dir + "/walk.c3d", std::ios::binary) << cpgait::testing::format_c3d_z_up(trial);
  const std::string model = cpgait::refdata::fixture("models/walker.osim");
  ASSERT_EQ(run("ik --model " + model + " --markers " + dir + "/walk.trc -o " + dir + "/trc").status, 0);
  const CliRun c3d = run("ik --model " + model + " --markers " + dir + "/walk.c3d -o " + dir + "/c3d");
  ASSERT_EQ(c3d.status, 0) << c3d.output;
  const cpgait::Storage a = cpgait::read_storage(dir + "/trc/walk_ik.mot"), b = cpgait::read_storage(dir + "/c3d/walk_ik.mot");
  ASSERT_EQ(a.num_rows(), b.num_rows());
  ASSERT_EQ(a.labels, b.labels);
  // Floats hold the markers to ~1e-5 mm; the coordinates agree far below a degree (degrees or m).
  EXPECT_LT((a.data - b.data).cwiseAbs().maxCoeff(), 1e-3);
  std::printf("[ info ] IK from the C3D against the TRC: largest difference %.2e (deg or m)\n", (a.data - b.data).cwiseAbs().maxCoeff());
  // Read as recorded (--c3d-vertical y) the lab is on its side: IK fits it, but not as the TRC.
  ASSERT_EQ(run("ik --model " + model + " --markers " + dir + "/walk.c3d --c3d-vertical y -o " + dir + "/sideways").status, 0);
  EXPECT_GT((a.data - cpgait::read_storage(dir + "/sideways/walk_ik.mot").data).cwiseAbs().maxCoeff(), 10.0);
  // convert: the TRC, markers as the C3D reads them, gaps kept.
  const CliRun conv = run("convert " + dir + "/walk.c3d -o " + dir + "/converted");
  ASSERT_EQ(conv.status, 0) << conv.output;
  const cpgait::MarkerTrial back = cpgait::read_marker_file(dir + "/converted/walk.trc");
  ASSERT_EQ(back.marker_names, trial.marker_names);
  ASSERT_EQ(back.num_frames(), trial.num_frames());
  EXPECT_EQ(back.gaps().size(), trial.gaps().size());
  EXPECT_GT(trial.gaps().size(), 0u);
  const Eigen::Matrix3Xd d = back.positions_m - trial.positions_m;
  double largest = 0;
  for (Eigen::Index k = 0; k < d.cols(); ++k)
    if (trial.positions_m.col(k).allFinite()) largest = std::max(largest, d.col(k).cwiseAbs().maxCoeff());
  EXPECT_LT(largest, 1e-7) << "m";
  std::printf("[ info ] converted TRC against the trial: largest marker difference %.2e m\n", largest);
  // A damaged C3D is refused with the byte and the field.
  std::string damaged = cpgait::text::read_file(dir + "/walk.c3d");
  damaged.resize(damaged.size() / 2);
  std::ofstream(dir + "/damaged.c3d", std::ios::binary) << damaged;
  const CliRun bad = run("ik --model " + model + " --markers " + dir + "/damaged.c3d -o " + dir + "/bad");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.output.find("damaged.c3d: data"), std::string::npos) << bad.output;
  fs::remove_all(dir);
}
