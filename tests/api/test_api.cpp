// The REST service against a real server process on 127.0.0.1.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/fixtures/tag_footage.h"
#include "cpgait/model/osim_reader.h"
#include "c3d_writer.h"
#include "json_schema_check.h"
#include "api_helpers.h"
#include "server_process.h"
#include "test_support.h"

// Last: httplib pulls in <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace fs = std::filesystem;
using nlohmann::json;
using cpgait::apitest::ServerProcess;
using namespace cpgait::apitest;

// Under CPGAIT_TEST_STORE=postgresql (ctest's Postgres.* copies of these tests) every server keeps
// its store in PostgreSQL; without a server to use, they all skip.
class StoreEnvironment : public ::testing::Environment {
 public:
  void SetUp() override {
    if (store_is_postgres()) REQUIRE_POSTGRES();
  }
};
const auto* const kStoreEnvironment = ::testing::AddGlobalTestEnvironment(new StoreEnvironment);

namespace {

int run_cli(const std::string& args) {
  const int s = std::system((std::string(CPGAIT_BINARY) + " " + args + " > /dev/null 2>&1").c_str());
  return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

const std::vector<std::string> kResultSuffixes = {"_ik.mot",
                                                  "_ik_marker_errors.sto",
                                                  "_id.sto",
                                                  "_StaticOptimization_activation.sto",
                                                  "_StaticOptimization_force.sto",
                                                  "_cpg.json",
                                                  "_gait.mot",
                                                  "_gait_residuals.sto"};

}  // namespace

// Acceptance 1: upload subject01, follow the SSE stream to completion, and check that the served
// files equal what `cpgait run` writes for the same inputs; and that job.json reproduces them.
TEST(ApiReference, Subject01UploadMatchesCliRun) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  const std::string generic = cpgait::refdata::gait2392("model/gait2392_simbody.osim");
  for (const auto& f : {"OutputReference/subject01_simbody.osim", "subject01_walk1.trc", "subject01_walk1_grf.mot", "subject01_walk1_grf.xml",
                        "subject01_Setup_IK.xml"})
    REQUIRE_REFERENCE(pl + f);
  REQUIRE_REFERENCE(generic);
  const std::string dir = cpgait::refdata::temp_dir("api_subject01");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());

  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{
                                        {"model", slurp(pl + "OutputReference/subject01_simbody.osim"), "subject01_simbody.osim", "application/xml"}});
  ASSERT_TRUE(m);
  ASSERT_EQ(m->status, 201) << m->body;
  const std::string model_id = body(m)["id"];
  EXPECT_TRUE(body(m)["warnings"].is_array());

  // The generic model the subject's was scaled from (its muscle lengths: scale_muscle_parameters.h).
  auto g = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", slurp(generic), "gait2392_simbody.osim", "application/xml"}});
  ASSERT_TRUE(g);
  ASSERT_EQ(g->status, 201) << g->body;
  const std::string generic_id = body(g)["id"];
  // A model id that does not exist is refused, naming the field.
  const json bad = {{"model", model_id}, {"scale_muscles_from", "no-such-model"}};
  auto refused = c.Post("/api/v1/trials", trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", bad));
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 422);
  EXPECT_EQ(body(refused)["error"]["field"], "scale_muscles_from");

  // The whole trial (two gait cycles for the reproduced gait, held by residuals), the IK setup's marker weights.
  const json options = {{"model", model_id},
                        {"scale_muscles_from", generic_id},
                        {"ik", {{"tasks", json::parse(cpgait::ik_tasks_json(cpgait::read_ik_tasks(pl + "subject01_Setup_IK.xml")))}}},
                        {"gait", json::parse(cpgait::refdata::kResidualGaitOptions)}};
  httplib::MultipartFormDataItems form = trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", options);
  form.push_back({"grf", slurp(pl + "subject01_walk1_grf.mot"), "subject01_walk1_grf.mot", "text/plain"});
  form.push_back({"loads", slurp(pl + "subject01_walk1_grf.xml"), "subject01_walk1_grf.xml", "application/xml"});
  auto t = c.Post("/api/v1/trials", form);
  ASSERT_TRUE(t);
  ASSERT_EQ(t->status, 202) << t->body;
  const std::string id = body(t)["id"];
  int progress = 0;
  EXPECT_EQ(follow_events(c, id, &progress), "done") << server.log();
  EXPECT_GT(progress, 3);
  const json trial = body(c.Get(("/api/v1/trials/" + id).c_str()));
  EXPECT_EQ(trial["status"], "done");
  // Every stage ran but CMC: static optimization is the default activation.
  for (const auto& s : trial["stages"]) EXPECT_EQ(s["state"], s["name"] == "cmc" ? "skipped" : "done") << s.dump();
  // The reproduced gait through the service: two cycles, the ground carrying the body.
  json gait;
  for (const auto& s : trial["stages"])
    if (s["name"] == "gait") gait = s["summary"];
  ASSERT_TRUE(gait.is_object()) << trial.dump();
  EXPECT_TRUE(gait["fell_at_s"].is_null()) << gait.dump();
  EXPECT_GT(gait["simulated_s"].get<double>(), 2.4);
  EXPECT_LT(gait["pelvis_residual_force_percent_bw"].get<double>(), 10.0);

  // The CLI on the same inputs and options.
  std::ofstream(dir + "/options.json") << options.dump();
  ASSERT_EQ(run_cli("run --model " + pl + "OutputReference/subject01_simbody.osim --scale-muscles-from " + generic + " --markers " + pl +
                    "subject01_walk1.trc --grf " + pl +
                    "subject01_walk1_grf.mot --loads " + pl + "subject01_walk1_grf.xml --options " + dir + "/options.json -o " + dir + "/cli"),
            0);
  for (const auto& suffix : kResultSuffixes) {
    const std::string name = "subject01_walk1" + suffix;
    auto f = c.Get(("/api/v1/trials/" + id + "/files/" + name).c_str());
    ASSERT_TRUE(f);
    ASSERT_EQ(f->status, 200) << name;
    EXPECT_EQ(f->body, slurp(dir + "/cli/" + name)) << name << " differs between the service and cpgait run";
  }
  // The service's job.json follows the schema it publishes.
  const json schema = body(c.Get("/api/v1/options/schema"));
  auto job = c.Get(("/api/v1/trials/" + id + "/files/job.json").c_str());
  ASSERT_EQ(job->status, 200);
  const auto violations = cpgait::testing::schema_violations(schema, json::parse(job->body));
  EXPECT_TRUE(violations.empty()) << violations.front();
  // job.json alone reproduces the run.
  ASSERT_EQ(run_cli("run --options " + dir + "/cli/job.json -o " + dir + "/cli2"), 0);
  for (const auto& suffix : kResultSuffixes)
    EXPECT_EQ(slurp(dir + "/cli/subject01_walk1" + suffix), slurp(dir + "/cli2/subject01_walk1" + suffix)) << suffix;

  // With "activation": "cmc" (the seed method): CMC instead of static optimization, the CPG fitted to
  // its excitations, the reproduced gait on compliant tendons.
  json cmc_options = options;
  cmc_options["activation"] = "cmc";
  form = trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", cmc_options);
  form.push_back({"grf", slurp(pl + "subject01_walk1_grf.mot"), "subject01_walk1_grf.mot", "text/plain"});
  form.push_back({"loads", slurp(pl + "subject01_walk1_grf.xml"), "subject01_walk1_grf.xml", "application/xml"});
  auto tc = c.Post("/api/v1/trials", form);
  ASSERT_TRUE(tc);
  ASSERT_EQ(tc->status, 202) << tc->body;
  const std::string cmc_id = body(tc)["id"];
  EXPECT_EQ(follow_events(c, cmc_id, &progress), "done") << server.log();
  const json cmc_trial = body(c.Get(("/api/v1/trials/" + cmc_id).c_str()));
  json by_stage = json::object();
  for (const auto& s : cmc_trial["stages"]) by_stage[s["name"].get<std::string>()] = s;
  EXPECT_EQ(by_stage["so"]["state"], "skipped");
  ASSERT_EQ(by_stage["cmc"]["state"], "done") << cmc_trial.dump();
  // Within 1 deg (1 mm) RMS; 2 deg at the toes, which no gait2392 muscle crosses (their 1 N m reserves
  // alone move them; measured 1.37 deg).
  for (const auto& [coordinate, rms] : by_stage["cmc"]["summary"]["tracking_error_rms_deg_or_mm"].items())
    EXPECT_LT(rms.get<double>(), coordinate.rfind("mtp_angle", 0) == 0 ? 2.0 : 1.0) << coordinate;
  const json cpg = by_stage["cpg"]["summary"];
  EXPECT_EQ(cpg["fitted_to"], "cmc excitations");
  std::printf("[ info ] CPG fitted to CMC excitations: mean R^2 %.3f over %d active muscles\n", cpg["mean_r_squared_active"].get<double>(),
              cpg["active_muscles"].get<int>());
  EXPECT_GT(cpg["mean_r_squared_active"].get<double>(), 0.6);
  EXPECT_EQ(by_stage["gait"]["state"], "done");
  EXPECT_EQ(by_stage["gait"]["summary"]["compliant_tendons"], true);
  EXPECT_GT(by_stage["gait"]["summary"]["simulated_s"].get<double>(), 0.5);
  auto controls = c.Get(("/api/v1/trials/" + cmc_id + "/files/subject01_walk1_cmc_controls.sto").c_str());
  ASSERT_TRUE(controls);
  EXPECT_EQ(controls->status, 200);

  // The reproduced gait laid on the trial's frames for the overlay: a subset of IK's times.
  const json ik_kin = body(c.Get(("/api/v1/trials/" + id + "/kinematics").c_str()));
  const json gait_kin = body(c.Get(("/api/v1/trials/" + id + "/kinematics?source=gait").c_str()));
  ASSERT_TRUE(gait_kin.contains("frames")) << gait_kin.dump().substr(0, 300);
  ASSERT_GT(gait_kin["frames"].size(), 10u);
  std::set<double> ik_times;
  for (const auto& f : ik_kin["frames"]) ik_times.insert(f["time"].get<double>());
  for (const auto& f : gait_kin["frames"]) EXPECT_TRUE(ik_times.count(f["time"].get<double>())) << f["time"];
  EXPECT_EQ(c.Get(("/api/v1/trials/" + id + "/kinematics?source=cmc").c_str())->status, 400);

  // Results as columns.
  const json so = body(c.Get(("/api/v1/trials/" + id + "/results/so").c_str()));
  ASSERT_EQ(so["tables"].size(), 2u);
  EXPECT_EQ(so["tables"][0]["labels"].size(), 1u + 92u + 23u);  // time, muscles, one actuator per coordinate
  EXPECT_EQ(so["tables"][0]["rows"], 151);
  fs::remove_all(dir);
}

// Gait-cycle curves for the review (issue 26): every stride cut at its foot's force-plate heel
// strikes and resampled to 0-100 %, the strides' mean and SD.
TEST(ApiReference, GaitCyclesCutEachStrideAtItsHeelStrikes) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  for (const auto& f : {"OutputReference/subject01_simbody.osim", "subject01_walk1.trc", "subject01_walk1_grf.mot"}) REQUIRE_REFERENCE(pl + f);
  const std::string dir = cpgait::refdata::temp_dir("api_cycles");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{
                                        {"model", slurp(pl + "OutputReference/subject01_simbody.osim"), "subject01_simbody.osim", ""}});
  ASSERT_EQ(m->status, 201);
  httplib::MultipartFormDataItems form =
      trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", {{"model", body(m)["id"]}, {"stages", {"ik", "id", "so"}}});
  form.push_back({"grf", slurp(pl + "subject01_walk1_grf.mot"), "subject01_walk1_grf.mot", ""});
  form.push_back({"loads", slurp(pl + "subject01_walk1_grf.xml"), "subject01_walk1_grf.xml", ""});
  const std::string id = body(c.Post("/api/v1/trials", form))["id"];
  EXPECT_EQ(c.Get("/api/v1/trials/ffffffffffffffff/cycles")->status, 404);
  ASSERT_EQ(wait_finished(c, id, 120), "done");
  const json cy = body(c.Get(("/api/v1/trials/" + id + "/cycles").c_str()));
  ASSERT_EQ(cy["percent"].size(), 101u) << cy.dump().substr(0, 300);
  EXPECT_EQ(cy["percent"][100], 100);
  for (const char* side : {"r", "l"}) {
    EXPECT_EQ(cy["heel_strike_source"][side].get<std::string>().rfind("GRF", 0), 0u) << cy["heel_strike_source"];
    EXPECT_GE(cy["heel_strikes_s"][side].size(), 2u);
  }
  std::map<std::string, json> panels;
  for (const auto& p : cy["panels"]) panels[p["name"]] = p;
  ASSERT_EQ(panels.size(), 3u);
  EXPECT_EQ(panels["activations"]["series"].size(), 92u);  // the muscles; reserves and residuals left out
  // Each stride starts and ends where IK was at its heel strikes; the mean is the strides' mean.
  const json ik = body(c.Get(("/api/v1/trials/" + id + "/results/ik").c_str()))["tables"][0];
  const auto& labels = ik["labels"];
  const std::vector<double> t = ik["columns"][0];
  auto ik_at = [&](const std::string& name, double time) {
    const std::size_t col = static_cast<std::size_t>(std::find(labels.begin(), labels.end(), name) - labels.begin());
    const std::vector<double> v = ik["columns"][col];
    const std::size_t i = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), time) - t.begin());
    const double a = (time - t[i - 1]) / (t[i] - t[i - 1]);
    return (1 - a) * v[i - 1] + a * v[i];
  };
  int checked = 0;
  for (const auto& s : panels["kinematics"]["series"]) {
    const std::string name = s["name"], side = s["side"];
    const std::vector<double> hs = cy["heel_strikes_s"][side];
    ASSERT_GE(s["strides"].size(), 1u) << name;
    const std::vector<double> first = s["strides"][0];
    const std::size_t k0 = static_cast<std::size_t>(std::find_if(hs.begin(), hs.end(), [&](double h) { return h >= t.front() - 1e-9; }) - hs.begin());
    EXPECT_NEAR(first.front(), ik_at(name, hs[k0]), 1e-9) << name;
    EXPECT_NEAR(first.back(), ik_at(name, hs[k0 + 1]), 1e-9) << name;
    for (std::size_t k = 0; k < 101; ++k) {
      double mean = 0;
      for (const auto& stride : s["strides"]) mean += stride[k].get<double>();
      EXPECT_NEAR(s["mean"][k].get<double>(), mean / static_cast<double>(s["strides"].size()), 1e-12) << name << " at " << k << " %";
      EXPECT_GE(s["sd"][k].get<double>(), 0.0);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 23);

  // The report (acceptance 3): one self-contained page with the cycle plots as images.
  auto report = c.Get(("/api/v1/trials/" + id + "/report").c_str());
  ASSERT_EQ(report->status, 200);
  EXPECT_EQ(report->get_header_value("Content-Type").rfind("text/html", 0), 0u);
  EXPECT_NE(report->get_header_value("Content-Disposition").find("subject01_walk1_report.html"), std::string::npos);
  const std::string& html = report->body;
  EXPECT_LT(html.size(), 2u << 20);
  for (const char* external : {"<script", "<link", "src=\"http", "href=\"http", "url("}) EXPECT_EQ(html.find(external), std::string::npos) << external;
  std::size_t images = 0;
  for (std::size_t p = 0; (p = html.find("<img ", p)) != std::string::npos; ++p) {
    ++images;
    const std::string inline_svg = "src=\"data:image/svg+xml;base64,PHN2Zy";  // "<svg" in base64
    EXPECT_EQ(html.compare(html.find("src=", p), inline_svg.size(), inline_svg), 0) << "an image that is not an inline SVG";
  }
  // hip, knee and ankle angles, pelvis tilt, hip adduction, subtalar; three moments; seven muscles.
  EXPECT_EQ(images, 16u);
  EXPECT_NE(html.find("knee_angle_r"), std::string::npos);
  fs::remove_all(dir);
}

// Bones for the 3-D view (issue 26): mesh files uploaded with a model (or in a --geometry folder)
// are served as triangles; the trial's kinematics say which body carries which, scaled.
TEST(ApiReference, ModelMeshesAreUploadedCheckedAndServed) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  const std::string geometry = cpgait::refdata::shared_path("opensim/Geometry");
  REQUIRE_REFERENCE(pl + "OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(geometry + "/femur_r.vtp");
  const std::string dir = cpgait::refdata::temp_dir("api_meshes");
  ServerProcess server(dir + "/data", {"--geometry", geometry});
  httplib::Client c("127.0.0.1", server.port());
  const std::string osim = slurp(pl + "OutputReference/subject01_simbody.osim");
  // A broken mesh part is refused, naming the part and the file; nothing is stored.
  auto bad = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", osim, "subject01_simbody.osim", ""},
                                                                      {"geometry", "v 0 0 0\nf 1 2 3\n", "broken.obj", ""}});
  ASSERT_EQ(bad->status, 422) << bad->body;
  EXPECT_EQ(body(bad)["error"]["part"], "geometry");
  EXPECT_NE(body(bad)["error"]["message"].get<std::string>().find("broken.obj"), std::string::npos);
  EXPECT_EQ(body(c.Get("/api/v1/models"))["models"].size(), 1u);  // the built-in walker only
  // An uploaded femur (a made one, to tell it from the --geometry folder's) wins over the folder's.
  const std::string own_femur = "v 0 0 0\nv 0 -0.5 0\nv 0.05 -0.5 0\nf 1 2 3\n";
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", osim, "subject01_simbody.osim", ""},
                                                                    {"geometry", own_femur, "femur_r.vtp.obj", ""}});
  ASSERT_EQ(m->status, 201) << m->body;
  const std::string model = body(m)["id"];
  const json own = body(c.Get(("/api/v1/models/" + model + "/meshes/femur_r.vtp.obj").c_str()));
  EXPECT_EQ(own["triangles"].size(), 3u);
  const json femur = body(c.Get(("/api/v1/models/" + model + "/meshes/femur_r.vtp").c_str()));
  EXPECT_EQ(femur["positions"].size(), 3u * 456);
  EXPECT_EQ(femur["triangles"].size(), 3u * 908);
  EXPECT_EQ(c.Get(("/api/v1/models/" + model + "/meshes/nothing.vtp").c_str())->status, 404);
  const auto escape = c.Get(("/api/v1/models/" + model + "/meshes/..%2Fmodel.osim").c_str());
  EXPECT_TRUE(escape->status == 400 || escape->status == 404) << escape->status;  // never the model file
  EXPECT_EQ(escape->body.find("OpenSimDocument"), std::string::npos);
  // A trial's kinematics name each body's meshes with their scale.
  auto t = c.Post("/api/v1/trials", trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", {{"model", model}, {"stages", {"ik"}}}));
  const std::string id = body(t)["id"];
  ASSERT_EQ(wait_finished(c, id, 60), "done");
  const json kin = body(c.Get(("/api/v1/trials/" + id + "/kinematics").c_str()));
  int meshes = 0;
  for (const auto& b : kin["bodies"]) {
    meshes += static_cast<int>(b["meshes"].size());
    if (b["name"] == "femur_r") {
      EXPECT_NEAR(b["meshes"][0]["scale"][0].get<double>(), 1.14724, 1e-9);
    }
  }
  EXPECT_EQ(meshes, 19);
  EXPECT_EQ(kin["muscle_names"].size(), 92u);
  EXPECT_GE(kin["frames"][0]["muscles"][0].size(), 6u);  // two points or more, x y z each
  fs::remove_all(dir);
}

// A model zipped with its Geometry folder, as a lab keeps it (Info-ZIP, with a macOS resource fork
// and a readme): the model and every mesh are taken from the archive; a second model, a broken mesh
// or a broken archive is a 422 naming the part and the file, and stores nothing.
TEST(ApiReference, ZippedModelWithItsGeometryFolder) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  const std::string geometry = cpgait::refdata::shared_path("opensim/Geometry");
  REQUIRE_REFERENCE(pl + "OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(geometry + "/femur_r.vtp");
  if (std::system("command -v zip > /dev/null 2>&1") != 0) GTEST_SKIP() << "Info-ZIP's zip is absent (./install-deps.sh installs it)";
  const std::string dir = cpgait::refdata::temp_dir("api_zip");
  fs::create_directories(dir + "/lab/subject01/Geometry");
  fs::copy_file(pl + "OutputReference/subject01_simbody.osim", dir + "/lab/subject01/subject01_simbody.osim");
  int vtp = 0;
  for (const auto& f : fs::directory_iterator(geometry))
    if (f.path().extension() == ".vtp") fs::copy_file(f.path(), dir + "/lab/subject01/Geometry/" + f.path().filename().string()), ++vtp;
  std::ofstream(dir + "/lab/subject01/README.txt") << "subject01, scaled\n";
  std::ofstream(dir + "/lab/subject01/Geometry/._femur_r.vtp") << "AppleDouble";
  auto zip = [&](const std::string& name, const std::string& what) {
    EXPECT_EQ(std::system(("cd '" + dir + "/lab' && zip -q -r '" + dir + "/" + name + "' " + what).c_str()), 0);
    return slurp(dir + "/" + name);
  };
  const std::string archive = zip("subject01.zip", "subject01");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", archive, "subject01.zip", "application/zip"}});
  ASSERT_EQ(m->status, 201) << m->body;
  const std::string model = body(m)["id"];
  EXPECT_EQ(body(m)["summary"]["meshes"], vtp);
  EXPECT_EQ(body(m)["summary"]["muscles"], 92);
  EXPECT_NE(body(m)["warnings"].dump().find("README.txt"), std::string::npos) << body(m)["warnings"];
  const json listed = body(c.Get("/api/v1/models"))["models"];
  EXPECT_EQ(listed.back()["name"], "subject01_simbody.osim");
  // Served from the model's own Geometry (this server has no --geometry folder).
  const json femur = body(c.Get(("/api/v1/models/" + model + "/meshes/femur_r.vtp").c_str()));
  EXPECT_EQ(femur["triangles"].size(), 3u * 908);

  auto refused = [&](const std::string& bytes) {
    auto r = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", bytes, "lab.zip", "application/zip"}});
    EXPECT_EQ(r->status, 422) << r->body;
    return body(r)["error"];
  };
  fs::copy_file(dir + "/lab/subject01/subject01_simbody.osim", dir + "/lab/subject01/copy.osim");
  const json two = refused(zip("two.zip", "subject01"));
  EXPECT_NE(two["message"].get<std::string>().find("2 .osim models"), std::string::npos) << two;
  fs::remove(dir + "/lab/subject01/copy.osim");
  std::ofstream(dir + "/lab/subject01/Geometry/broken.stl") << "solid x\nfacet normal 0 0 1\n";
  const json broken = refused(zip("broken.zip", "subject01"));
  EXPECT_EQ(broken["part"], "geometry");
  EXPECT_NE(broken["message"].get<std::string>().find("lab.zip:subject01/Geometry/broken.stl"), std::string::npos) << broken;
  std::string cut = archive.substr(0, archive.size() / 2);
  EXPECT_EQ(refused(cut)["part"], "model");
  EXPECT_EQ(body(c.Get("/api/v1/models"))["models"].size(), 2u);  // the walker and subject01 only
  fs::remove_all(dir);
}

// subject01 walked on a treadmill (its pelvis stays within 2 cm over 3.5 s): the review finds the
// belt from the stance feet. The same markers carried forward at u m/s move the belt estimate by
// exactly u; carried at the belt's own speed they walk overground, and there is no belt.
TEST(ApiReference, TreadmillBeltFromTheStanceFeet) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  REQUIRE_REFERENCE(pl + "OutputReference/subject01_simbody.osim");
  REQUIRE_REFERENCE(pl + "subject01_walk1.trc");
  const std::string dir = cpgait::refdata::temp_dir("api_treadmill");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{
                                        {"model", slurp(pl + "OutputReference/subject01_simbody.osim"), "subject01_simbody.osim", ""}});
  ASSERT_EQ(m->status, 201) << m->body;
  const std::string model = body(m)["id"];
  const cpgait::MarkerTrial recorded = cpgait::read_trc(pl + "subject01_walk1.trc");
  auto kinematics = [&](double carried_m_s) {
    cpgait::MarkerTrial moved = recorded;
    for (int f = 0; f < moved.num_frames(); ++f)
      for (int k = 0; k < moved.num_markers(); ++k) moved.position_m(f, k).x() += carried_m_s * moved.time_s[f];
    auto t = c.Post("/api/v1/trials", trial_form(cpgait::format_trc(moved), "walk.trc", {{"model", model}, {"stages", {"ik"}}}));
    const std::string id = body(t)["id"];
    EXPECT_EQ(wait_finished(c, id, 60), "done");
    return body(c.Get(("/api/v1/trials/" + id + "/kinematics").c_str()));
  };
  const json as_recorded = kinematics(0.0);
  ASSERT_TRUE(as_recorded["treadmill"].is_object()) << as_recorded["treadmill"];
  const double belt = as_recorded["treadmill"]["belt_velocity_m_s"][0];
  std::printf("[info] subject01's treadmill belt: %.3f m/s along x, %.4f along z\n", belt,
              as_recorded["treadmill"]["belt_velocity_m_s"][2].get<double>());
  EXPECT_LT(belt, -0.8);  // backwards, at a walking speed
  EXPECT_GT(belt, -1.6);
  const json carried = kinematics(0.5);
  ASSERT_TRUE(carried["treadmill"].is_object());
  EXPECT_NEAR(carried["treadmill"]["belt_velocity_m_s"][0].get<double>(), belt + 0.5, 0.01);
  EXPECT_TRUE(kinematics(-belt)["treadmill"].is_null());
  fs::remove_all(dir);
}

// Large JSON leaves gzip-compressed even to clients that also accept Brotli: the HTTP library's
// Brotli (quality 11) took 38 s over a 15 s trial's 18 MB kinematics.
TEST(Api, JsonIsSentWithGzipNotBrotli) {
  const std::string dir = cpgait::refdata::temp_dir("api_encoding");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto t = c.Post("/api/v1/trials", trial_form(synthetic_trc(2.0), "walk.trc", {{"model", "walker"}, {"stages", {"ik"}}}));
  const std::string id = body(t)["id"];
  ASSERT_EQ(wait_finished(c, id, 60), "done");
  for (const char* accepted : {"gzip, deflate, br", "br;q=1.0, gzip;q=0.8", "br"}) {
    auto r = c.Get(("/api/v1/trials/" + id + "/kinematics").c_str(), {{"Accept-Encoding", accepted}});
    ASSERT_EQ(r->status, 200) << accepted;
    EXPECT_EQ(r->get_header_value("Content-Encoding"), std::string(accepted) == "br" ? "" : "gzip") << accepted;
    EXPECT_TRUE(body(r)["frames"].is_array()) << accepted;  // decompressed by the client
  }
  fs::remove_all(dir);
}

TEST(ApiReference, ModelWithSeparateMarkerSet) {
  const std::string model = cpgait::refdata::gait2392("model/gait2392_simbody.osim");
  const std::string markers = cpgait::refdata::gait2392("pipeline/gait2392_Scale_MarkerSet.xml");
  REQUIRE_REFERENCE(model);
  REQUIRE_REFERENCE(markers);
  const std::string dir = cpgait::refdata::temp_dir("api_markerset");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto bare = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", slurp(model), "gait2392_simbody.osim", ""}});
  auto with = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", slurp(model), "gait2392_simbody.osim", ""},
                                                                       {"markerset", slurp(markers), "markers.xml", ""}});
  ASSERT_EQ(bare->status, 201) << bare->body;
  ASSERT_EQ(with->status, 201) << with->body;
  EXPECT_GT(body(with)["summary"]["markers"].get<int>(), body(bare)["summary"]["markers"].get<int>());
  EXPECT_TRUE(body(with)["summary"]["markerset"].get<bool>());
  auto broken = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", slurp(model), "g.osim", ""},
                                                                         {"markerset", "<MarkerSet>\n<objects>", "m.xml", ""}});
  EXPECT_EQ(broken->status, 422);
  EXPECT_EQ(json::parse(broken->body)["error"]["part"], "markerset");
  EXPECT_EQ(body(c.Get("/api/v1/models"))["models"].size(), 3u);  // built-in + the two good ones
  fs::remove_all(dir);
}

// Issue 20, acceptance 4 through the service: the generic gait2392 (with its scale marker set), the
// static trial and the ScaleTool setup uploaded with the walk; the scale stage runs first and the
// served results equal `cpgait run --generic-model` on the same files; the review's kinematics use the
// scaled model. A setup without its static trial, and a static trial that is not one, are refused.
TEST(ApiReference, GenericModelAndStaticTrialAreScaledFirst) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  const std::string generic = cpgait::refdata::gait2392("model/gait2392_simbody.osim");
  for (const auto& f : {"gait2392_Scale_MarkerSet.xml", "subject01_static.trc", "subject01_Setup_Scale.xml", "subject01_walk1.trc",
                        "subject01_walk1_grf.mot", "subject01_walk1_grf.xml", "subject01_Setup_IK.xml"})
    REQUIRE_REFERENCE(pl + f);
  REQUIRE_REFERENCE(generic);
  const std::string dir = cpgait::refdata::temp_dir("api_scale");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", slurp(generic), "gait2392_simbody.osim", ""},
                                                                    {"markerset", slurp(pl + "gait2392_Scale_MarkerSet.xml"), "markers.xml", ""}});
  ASSERT_EQ(m->status, 201) << m->body;
  const json options = {{"model", body(m)["id"]},
                        {"stages", {"ik", "id", "so"}},
                        {"ik", {{"tasks", json::parse(cpgait::ik_tasks_json(cpgait::read_ik_tasks(pl + "subject01_Setup_IK.xml")))}}}};
  auto form = [&](bool with_static, const std::string& static_text) {
    httplib::MultipartFormDataItems f = trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", options);
    f.push_back({"grf", slurp(pl + "subject01_walk1_grf.mot"), "subject01_walk1_grf.mot", "text/plain"});
    f.push_back({"loads", slurp(pl + "subject01_walk1_grf.xml"), "subject01_walk1_grf.xml", "application/xml"});
    f.push_back({"scale_setup", slurp(pl + "subject01_Setup_Scale.xml"), "subject01_Setup_Scale.xml", "application/xml"});
    if (with_static) f.push_back({"static", static_text, "subject01_static.trc", "text/plain"});
    return f;
  };
  auto no_static = c.Post("/api/v1/trials", form(false, ""));
  EXPECT_EQ(no_static->status, 400);
  EXPECT_EQ(body(no_static)["error"]["field"], "static");
  auto not_a_trial = c.Post("/api/v1/trials", form(true, "PathFileType\t4\nnot a trc\n"));
  EXPECT_EQ(not_a_trial->status, 422) << not_a_trial->body;
  EXPECT_EQ(body(not_a_trial)["error"]["part"], "static") << not_a_trial->body;

  auto t = c.Post("/api/v1/trials", form(true, slurp(pl + "subject01_static.trc")));
  ASSERT_EQ(t->status, 202) << t->body;
  const std::string id = body(t)["id"];
  EXPECT_EQ(follow_events(c, id), "done") << server.log();
  const json trial = body(c.Get(("/api/v1/trials/" + id).c_str()));
  ASSERT_EQ(trial["stages"][0]["name"], "scale");
  EXPECT_EQ(trial["stages"][0]["state"], "done");
  EXPECT_NEAR(trial["stages"][0]["summary"]["factors"]["pelvis"][0].get<double>(), 1.02458, 1e-5);

  std::ofstream(dir + "/options.json") << options.dump();
  ASSERT_EQ(run_cli("run --generic-model " + generic + " --marker-set " + pl + "gait2392_Scale_MarkerSet.xml --static " + pl +
                    "subject01_static.trc --scale-setup " + pl + "subject01_Setup_Scale.xml --markers " + pl + "subject01_walk1.trc --grf " +
                    pl + "subject01_walk1_grf.mot --loads " + pl + "subject01_walk1_grf.xml --options " + dir + "/options.json -o " + dir + "/cli"),
            0);
  for (const std::string suffix : {"_scaled.osim", "_scale_factors.sto", "_static_marker_errors.sto", "_ik.mot", "_id.sto",
                                   "_StaticOptimization_activation.sto"}) {
    auto f = c.Get(("/api/v1/trials/" + id + "/files/subject01_walk1" + suffix).c_str());
    ASSERT_EQ(f->status, 200) << suffix;
    EXPECT_EQ(f->body, slurp(dir + "/cli/subject01_walk1" + suffix)) << suffix << " differs between the service and cpgait run";
  }
  const json scale = body(c.Get(("/api/v1/trials/" + id + "/results/scale").c_str()));
  ASSERT_EQ(scale["tables"].size(), 2u) << scale.dump();
  const json kin = body(c.Get(("/api/v1/trials/" + id + "/kinematics").c_str()));
  ASSERT_TRUE(kin.contains("bodies")) << kin.dump().substr(0, 300);
  double mass = 0;  // the scaled model's (the subject's 72.6 kg), not the generic 75.16 kg
  for (const auto& b : kin["bodies"]) mass += b["mass_kg"].get<double>();
  EXPECT_NEAR(mass, 72.6, 1e-6);
  // No reproduced gait ran here (ik, id, so): none to lay over the trial.
  EXPECT_EQ(c.Get(("/api/v1/trials/" + id + "/kinematics?source=gait").c_str())->status, 409);
  fs::remove_all(dir);
}

// Acceptance 2: kill -9 during a job; after a restart every job ends complete and no finished
// result changed.
TEST(Api, KillDuringJobsThenRestartCompletesEverything) {
  const std::string dir = cpgait::refdata::temp_dir("api_restart");
  std::map<std::string, std::string> finished_before;  // file -> content
  std::vector<std::string> ids;
  std::string first;
  {
    ServerProcess server(dir + "/data", {"--workers", "1"});
    httplib::Client c("127.0.0.1", server.port());
    auto t = c.Post("/api/v1/trials", trial_form(synthetic_trc(1.0), "quick.trc", {{"model", "walker"}}));
    ASSERT_EQ(t->status, 202) << t->body;
    first = body(t)["id"];
    ASSERT_EQ(wait_finished(c, first, 60), "done");
    for (const auto& e : fs::directory_iterator(dir + "/data/trials/" + first + "/results"))
      finished_before[e.path().string()] = slurp(e.path().string());
    // Long trials (a minute of walking each) queue behind one worker.
    const std::string long_trc = synthetic_trc(60.0, 2);
    for (int i = 0; i < 3; ++i) {
      auto r = c.Post("/api/v1/trials", trial_form(long_trc, "long" + std::to_string(i) + ".trc", walker_with_residual_gait()));
      ASSERT_EQ(r->status, 202) << r->body;
      ids.push_back(body(r)["id"]);
    }
    // Wait until one is running, then crash the server.
    bool saw_running = false;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (!saw_running && std::chrono::steady_clock::now() < deadline) {
      saw_running = body(c.Get(("/api/v1/trials/" + ids[0]).c_str()))["status"] == "running";
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_TRUE(saw_running);
    server.stop(SIGKILL);
  }
  ServerProcess server(dir + "/data", {"--workers", "1"});
  httplib::Client c("127.0.0.1", server.port());
  for (const auto& id : ids) EXPECT_EQ(wait_finished(c, id, 180), "done") << server.log();
  EXPECT_NE(server.log().find("\"requeued\""), std::string::npos) << "the interrupted trial was not re-queued";
  for (const auto& [path, content] : finished_before) EXPECT_EQ(slurp(path), content) << path << " changed";
  for (const auto& id : ids) {
    EXPECT_FALSE(fs::exists(dir + "/data/trials/" + id + "/work"));
    EXPECT_TRUE(fs::exists(dir + "/data/trials/" + id + "/results/long" + std::to_string(&id - &ids[0]) + "_StaticOptimization_force.sto"));
  }
  fs::remove_all(dir);
}

// Acceptance 3: every kind of bad input gets the right status and a useful JSON message, and
// nothing is stored for a rejected upload.
TEST(Api, BadInputMatrix) {
  const std::string dir = cpgait::refdata::temp_dir("api_bad");
  ServerProcess server(dir + "/data", {"--max-upload-mb", "1"});
  httplib::Client c("127.0.0.1", server.port());
  const std::string trc = synthetic_trc(0.3);
  const json walker = {{"model", "walker"}};
  struct Case {
    std::string what;
    httplib::MultipartFormDataItems form;
    int status;
    std::string code, field;
    int line;
  };
  std::string bad_trc = trc;
  bad_trc.replace(bad_trc.find("\tmm\t"), 4, "\tft\t");
  std::string bad_cell = trc;
  {
    const std::size_t row = bad_cell.find("\n1\t");  // first data row: line 7
    bad_cell.insert(bad_cell.find('\t', bad_cell.find('\t', row + 1) + 1) + 1, "x");
  }
  std::vector<Case> cases = {
      {"no markers part", {{"options", walker.dump(), "o.json", ""}}, 400, "missing_part", "markers", 0},
      {"bad units", trial_form(bad_trc, "a.trc", walker), 422, "invalid_input", "Units", 3},
      {"non-numeric cell", trial_form(bad_cell, "a.trc", walker), 422, "invalid_input", "R.ASIS.X", 7},
      {"truncated TRC", trial_form(trc.substr(0, trc.size() / 2), "a.trc", walker), 422, "invalid_input", "", 0},
      {"malformed options JSON", trial_form(trc, "a.trc", json()), 400, "malformed_json", "options", 0},
      {"unknown option", trial_form(trc, "a.trc", {{"model", "walker"}, {"ik", {{"bound", "all"}}}}), 422, "invalid_input", "ik.bound", 0},
      {"mistyped option", trial_form(trc, "a.trc", {{"model", "walker"}, {"so", {{"activation_exponent", "two"}}}}), 422, "invalid_input",
       "so.activation_exponent", 0},
      {"unknown model", trial_form(trc, "a.trc", {{"model", "nope"}}), 422, "unknown_model", "model", 0},
      {"no model", trial_form(trc, "a.trc", json::object()), 422, "invalid_input", "model", 0},
      {"path traversal", trial_form(trc, "../../etc/passwd", walker), 400, "bad_file_name", "markers", 0},
      {"grf without loads", [&] {
         auto f = trial_form(trc, "a.trc", walker);
         f.push_back({"grf", "x\nendheader\ntime\ta\n0\t1\n", "g.mot", ""});
         return f;
       }(), 422, "invalid_input", "loads", 0},
      {"malformed loads XML", [&] {
         auto f = trial_form(trc, "a.trc", walker);
         f.push_back({"grf", "g\nendheader\ntime\tf_vx\tf_vy\tf_vz\n0\t1\t2\t3\n1\t1\t2\t3\n", "g.mot", ""});
         f.push_back({"loads", "<OpenSimDocument>\n<ExternalLoads>\n<objects>\n</ExternalLoads>", "l.xml", ""});
         return f;
       }(), 422, "invalid_input", "", 4},
  };
  // The cmc stage's OpenSim files: checked at upload when CMC is the activation.
  const json walker_cmc = {{"model", "walker"}, {"activation", "cmc"}};
  auto with_part = [&](const char* part, const std::string& content) {
    auto f = trial_form(trc, "a.trc", walker_cmc);
    f.push_back({part, content, std::string(part) + ".xml", ""});
    return f;
  };
  cases.push_back({"CMC task on an unknown coordinate",
                   with_part("cmc_tasks", "<OpenSimDocument Version=\"30000\">\n<CMC_TaskSet>\n<objects>\n"
                                          "<CMC_Joint name=\"knee\"><coordinate>knee_flexion_x</coordinate></CMC_Joint>\n"
                                          "</objects>\n</CMC_TaskSet>\n</OpenSimDocument>"),
                   422, "invalid_input", "coordinate", 4});
  cases.push_back({"malformed CMC actuators XML", with_part("cmc_actuators", "<ForceSet>\n<objects>\n</ForceSet>"), 422, "invalid_input", "", 3});
  cases[4].form[1].content = "{\"model\": ";
  for (const auto& k : cases) {
    auto r = c.Post("/api/v1/trials", k.form);
    ASSERT_TRUE(r) << k.what;
    EXPECT_EQ(r->status, k.status) << k.what << ": " << r->body;
    const json e = json::parse(r->body, nullptr, false);
    ASSERT_TRUE(e.contains("error")) << k.what << ": " << r->body;
    EXPECT_EQ(e["error"]["code"], k.code) << k.what << ": " << r->body;
    EXPECT_FALSE(e["error"]["message"].get<std::string>().empty()) << k.what;
    if (!k.field.empty()) {
      EXPECT_EQ(e["error"].value("field", ""), k.field) << k.what << ": " << r->body;
    }
    if (k.line > 0) {
      EXPECT_EQ(e["error"].value("line", 0), k.line) << k.what << ": " << r->body;
    }
    if (k.what.rfind("CMC", 0) == 0 || k.what.find("CMC") != std::string::npos) {
      EXPECT_EQ(e["error"].value("part", ""), k.what.find("actuators") != std::string::npos ? "cmc_actuators" : "cmc_tasks") << r->body;
    }
  }
  // Too large: 413 with a JSON body.
  auto big = c.Post("/api/v1/trials", trial_form(std::string(2 << 20, 'x'), "big.trc", walker));
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  EXPECT_EQ(json::parse(big->body)["error"]["code"], "payload_too_large");
  // Nothing was stored for any rejected upload.
  EXPECT_EQ(body(c.Get("/api/v1/trials"))["total"], 0);
  EXPECT_TRUE(fs::is_empty(dir + "/data/trials"));
  // Unknown ids, stages and files.
  EXPECT_EQ(c.Get("/api/v1/trials/0123456789abcdef")->status, 404);
  EXPECT_EQ(c.Get("/api/v1/trials/..%2F..%2Fetc")->status, 404);
  EXPECT_EQ(c.Delete("/api/v1/trials/0123456789abcdef")->status, 404);
  auto ok = c.Post("/api/v1/trials", trial_form(trc, "fine.trc", walker));
  ASSERT_EQ(ok->status, 202);
  const std::string id = body(ok)["id"];
  EXPECT_EQ(c.Get(("/api/v1/trials/" + id + "/results/xyz").c_str())->status, 404);
  EXPECT_EQ(wait_finished(c, id, 60), "done");
  EXPECT_EQ(c.Get(("/api/v1/trials/" + id + "/files/..%2Finputs%2Fmarkers.trc").c_str())->status, 400);
  EXPECT_EQ(c.Get(("/api/v1/trials/" + id + "/files/nothing.sto").c_str())->status, 404);
  EXPECT_EQ(c.Post(("/api/v1/trials/" + id + "/cancel").c_str())->status, 409);  // already done
  EXPECT_EQ(c.Get("/api/v1/trials?status=maybe")->status, 400);
  // A model that does not parse.
  auto bad_model = c.Post("/api/v1/models", httplib::MultipartFormDataItems{{"model", "<Model>\n<BodySet>", "bad.osim", ""}});
  EXPECT_EQ(bad_model->status, 422);
  EXPECT_EQ(json::parse(bad_model->body)["error"]["line"], 2);
  EXPECT_EQ(body(c.Get("/api/v1/models"))["models"].size(), 1u);  // only the built-in
  // The server survived all of it.
  EXPECT_EQ(c.Get("/healthz")->status, 200);
  fs::remove_all(dir);
}

// A lab's C3D as the markers part: read by content, turned Y-up, IK as from the TRC.
// OpenSim CMC files uploaded with a trial: the cmc stage tracks the task set's coordinates, with the
// uploaded actuators added to the model's, and says so; the files are kept with the trial's inputs.
TEST(Api, CmcFilesUploadedWithATrialAreUsed) {
  const std::string dir = cpgait::refdata::temp_dir("api_cmc_files");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto form = trial_form(synthetic_trc(0.4), "walk.trc", {{"model", "walker"}, {"activation", "cmc"}, {"stages", {"ik", "cmc"}}});
  form.push_back({"cmc_tasks",
                  "<OpenSimDocument Version=\"30000\"><CMC_TaskSet><objects>"
                  "<CMC_Joint name=\"hip\"><coordinate>hip_flexion_r</coordinate><kp>100</kp><kv>20</kv></CMC_Joint>"
                  "<CMC_Joint name=\"knee\"><coordinate>knee_angle_r</coordinate><kp>100</kp><kv>20</kv></CMC_Joint>"
                  "</objects></CMC_TaskSet></OpenSimDocument>",
                  "tasks.xml", ""});
  form.push_back({"cmc_actuators",
                  "<OpenSimDocument Version=\"30000\"><ForceSet><objects>"
                  "<CoordinateActuator name=\"hip_reserve\"><coordinate>hip_flexion_r</coordinate><optimal_force>5</optimal_force></CoordinateActuator>"
                  "</objects></ForceSet></OpenSimDocument>",
                  "reserves.xml", ""});
  auto r = c.Post("/api/v1/trials", form);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = body(r)["id"];
  ASSERT_EQ(wait_finished(c, id, 120), "done") << server.log();
  const json trial = body(c.Get(("/api/v1/trials/" + id).c_str()));
  json cmc;
  for (const auto& s : trial["stages"])
    if (s["name"] == "cmc") cmc = s;
  ASSERT_EQ(cmc["state"], "done") << trial.dump();
  EXPECT_EQ(cmc["summary"]["tasks"], "cmc_tasks.xml");  // as the worker reads it back from the trial's inputs
  EXPECT_EQ(cmc["summary"]["actuators"], "the model's and cmc_actuators.xml");
  auto forces = c.Get(("/api/v1/trials/" + id + "/files/walk_cmc_Actuation_force.sto").c_str());
  ASSERT_EQ(forces->status, 200);
  EXPECT_NE(forces->body.find("hip_reserve"), std::string::npos);
  EXPECT_EQ(forces->body.find("_residual"), std::string::npos);  // not the derived actuators
  fs::remove_all(dir);
}

TEST(Api, C3dMarkersUploadRunsLikeItsTrc) {
  const std::string dir = cpgait::refdata::temp_dir("api_c3d");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  const cpgait::Model m = cpgait::read_osim(cpgait::refdata::fixture("models/walker.osim")).model;
  cpgait::fixtures::SyntheticTrialOptions o;
  o.duration_s = 0.5;
  const cpgait::MarkerTrial trial = cpgait::fixtures::synthesize_trial(m, o).markers;
  const json options = {{"model", "walker"}, {"stages", {"ik"}}};
  const std::string from_trc = body(c.Post("/api/v1/trials", trial_form(cpgait::format_trc(trial, "mm"), "walk.trc", options)))["id"];
  auto posted = c.Post("/api/v1/trials", trial_form(cpgait::testing::format_c3d_z_up(trial), "walk.c3d", options));
  ASSERT_EQ(posted->status, 202) << posted->body;
  const std::string from_c3d = body(posted)["id"];
  ASSERT_EQ(wait_finished(c, from_trc, 60), "done");
  ASSERT_EQ(wait_finished(c, from_c3d, 60), "done");
  const json a = body(c.Get(("/api/v1/trials/" + from_trc + "/results/ik").c_str()));
  const json b = body(c.Get(("/api/v1/trials/" + from_c3d + "/results/ik").c_str()));
  ASSERT_EQ(a["tables"][0]["labels"], b["tables"][0]["labels"]);
  double largest = 0;
  for (std::size_t col = 1; col < a["tables"][0]["columns"].size(); ++col)
    for (std::size_t r = 0; r < a["tables"][0]["columns"][col].size(); ++r)
      largest = std::max(largest, std::abs(a["tables"][0]["columns"][col][r].get<double>() - b["tables"][0]["columns"][col][r].get<double>()));
  EXPECT_LT(largest, 1e-3) << "deg or m";
  // The review's kinematics read the C3D too.
  EXPECT_EQ(c.Get(("/api/v1/trials/" + from_c3d + "/kinematics").c_str())->status, 200);
  // A damaged one is refused with the byte offset.
  std::string damaged = cpgait::testing::format_c3d_z_up(trial);
  damaged.resize(damaged.size() / 2);
  auto refused = c.Post("/api/v1/trials", trial_form(damaged, "walk.c3d", options));
  EXPECT_EQ(refused->status, 422);
  EXPECT_NE(body(refused)["error"]["message"].get<std::string>().find("byte"), std::string::npos) << refused->body;
  fs::remove_all(dir);
}

// The stage table and the options schema, published; a trial's stages and job.json follow them.
// Issue 21, acceptance 3 through the service: subject01's walk and ground reactions as a C3D with two
// force plates, uploaded alone (no GRF parts): ID runs on the plates' loads, and the served files are
// `cpgait run`'s on the same C3D (which equal its run on `cpgait convert`'s files: C3dPipeline test).
TEST(ApiReference, C3dWithForcePlatesSuppliesTheGrf) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  for (const auto& f : {"OutputReference/subject01_simbody.osim", "subject01_walk1.trc", "subject01_walk1_grf.mot"})
    REQUIRE_REFERENCE(pl + f);
  const std::string dir = cpgait::refdata::temp_dir("api_c3d_plates");
  const cpgait::Storage grf = cpgait::read_storage(pl + "subject01_walk1_grf.mot");
  const std::string c3d = cpgait::testing::format_c3d_z_up_with_plates(cpgait::read_trc(pl + "subject01_walk1.trc"), grf.data, grf.labels,
                                                                      {"ground_force_", "1_ground_force_"}, 10);
  { std::ofstream(dir + "/walk.c3d", std::ios::binary) << c3d; }
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{
                                        {"model", slurp(pl + "OutputReference/subject01_simbody.osim"), "subject01_simbody.osim", ""}});
  ASSERT_EQ(m->status, 201) << m->body;
  const json options = {{"model", body(m)["id"]}, {"stages", {"ik", "id"}}};
  auto t = c.Post("/api/v1/trials", trial_form(c3d, "walk.c3d", options));
  ASSERT_EQ(t->status, 202) << t->body;
  const std::string id = body(t)["id"];
  ASSERT_EQ(wait_finished(c, id, 120), "done") << server.log();
  const json trial = body(c.Get(("/api/v1/trials/" + id).c_str()));
  for (const auto& s : trial["stages"])
    if (s["name"] == "id") {
      EXPECT_TRUE(s["summary"]["external_loads"].get<bool>()) << s.dump();
    }
  std::ofstream(dir + "/options.json") << json({{"stages", {"ik", "id"}}}).dump();
  ASSERT_EQ(run_cli("run --model " + pl + "OutputReference/subject01_simbody.osim --markers " + dir + "/walk.c3d --options " + dir +
                    "/options.json -o " + dir + "/cli"),
            0);
  for (const std::string suffix : {"_grf.mot", "_grf.xml", "_ik.mot", "_id.sto"}) {
    auto f = c.Get(("/api/v1/trials/" + id + "/files/walk" + suffix).c_str());
    ASSERT_EQ(f->status, 200) << suffix;
    EXPECT_TRUE(f->body == slurp(dir + "/cli/walk" + suffix)) << suffix << " differs between the service and cpgait run";
  }
  // The review shows the plates' forces.
  const json kin = body(c.Get(("/api/v1/trials/" + id + "/kinematics").c_str()));
  std::size_t forces = 0;
  for (const auto& frame : kin["frames"]) forces += frame["grf"].size();
  EXPECT_GT(forces, 100u);
  fs::remove_all(dir);
}

TEST(Api, PublishesItsStagesAndTheOptionsSchemaJobJsonFollows) {
  const std::string dir = cpgait::refdata::temp_dir("api_schema");
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  const json stages = body(c.Get("/api/v1/stages"))["stages"];
  std::vector<std::string> names, selectable;
  for (const auto& s : stages) {
    names.push_back(s["name"]);
    if (s["selectable"].get<bool>()) selectable.push_back(s["name"]);
    EXPECT_TRUE(s["needs"].is_array() && s["writes"].is_array() && !s["writes"].empty()) << s.dump();
  }
  EXPECT_EQ(names, (std::vector<std::string>{"scale", "capture", "ik", "id", "so", "cmc", "cpg", "gait"}));
  auto schema_response = c.Get("/api/v1/options/schema");
  ASSERT_EQ(schema_response->status, 200);
  const json schema = json::parse(schema_response->body);
  EXPECT_EQ(schema["properties"]["stages"]["items"]["enum"], json(selectable));
  // The CLI publishes the same schema.
  const std::string cli_schema = dir + "/schema.json";
  ASSERT_EQ(std::system((std::string(CPGAIT_BINARY) + " run --print-options-schema > " + cli_schema).c_str()), 0);
  EXPECT_EQ(json::parse(slurp(cli_schema)), schema);

  const json options = {{"model", "walker"}, {"stages", {"ik", "id"}}, {"id", {{"lowpass_cutoff_hz", 4}}}};
  const std::string id = body(c.Post("/api/v1/trials", trial_form(synthetic_trc(0.3), "s.trc", options)))["id"];
  ASSERT_EQ(wait_finished(c, id, 60), "done");
  const json trial = body(c.Get(("/api/v1/trials/" + id).c_str()));
  std::vector<std::string> trial_stages;
  for (const auto& s : trial["stages"]) trial_stages.push_back(s["name"]);
  // No static trial, no footage: neither the scale nor the capture stage.
  EXPECT_EQ(trial_stages, std::vector<std::string>(names.begin() + 2, names.end()));
  EXPECT_EQ(trial["stages"][1]["state"], "done");
  EXPECT_EQ(trial["stages"][2]["state"], "skipped");
  const json job = json::parse(c.Get(("/api/v1/trials/" + id + "/files/job.json").c_str())->body);
  EXPECT_EQ(job["id"]["lowpass_cutoff_hz"], 4.0);
  const auto violations = cpgait::testing::schema_violations(schema, job);
  EXPECT_TRUE(violations.empty()) << violations.front();
  // The checker is not vacuous: a mistyped field breaks the schema.
  json broken = job;
  broken["id"]["lowpass_cutoff_hz"] = "4";
  EXPECT_EQ(cpgait::testing::schema_violations(schema, broken).size(), 1u);
  fs::remove_all(dir);
}

TEST(Api, TokenCancelDeleteListAndMetrics) {
  const std::string dir = cpgait::refdata::temp_dir("api_token");
  ServerProcess server(dir + "/data", {"--token", "s3cret", "--workers", "1"});
  httplib::Client c("127.0.0.1", server.port());
  EXPECT_EQ(c.Get("/api/v1/trials")->status, 401);
  c.set_bearer_token_auth("wrong");
  auto wrong = c.Get("/api/v1/trials");
  EXPECT_EQ(wrong->status, 401);
  EXPECT_EQ(json::parse(wrong->body)["error"]["code"], "unauthorized");
  c.set_bearer_token_auth("s3cret");
  EXPECT_EQ(c.Get("/api/v1/trials")->status, 200);
  EXPECT_EQ(c.Get("/healthz")->status, 200);  // health needs no token
  // A long trial to cancel, a queued one behind it to cancel, a short one to keep.
  const std::string long_trc = synthetic_trc(60.0, 3);
  const std::string a = body(c.Post("/api/v1/trials", trial_form(long_trc, "a.trc", walker_with_residual_gait())))["id"];
  const std::string b = body(c.Post("/api/v1/trials", trial_form(long_trc, "b.trc", walker_with_residual_gait())))["id"];
  const std::string k = body(c.Post("/api/v1/trials", trial_form(synthetic_trc(0.3), "k.trc", {{"model", "walker"}, {"stages", {"ik"}}})))["id"];
  EXPECT_EQ(c.Post(("/api/v1/trials/" + b + "/cancel").c_str())->status, 202);
  const auto started_by = std::chrono::steady_clock::now() + std::chrono::seconds(60);  // liveness bound
  while (body(c.Get(("/api/v1/trials/" + a).c_str()))["status"] == "queued") {
    ASSERT_LT(std::chrono::steady_clock::now(), started_by) << "trial " << a << " never left the queue";
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_EQ(c.Post(("/api/v1/trials/" + a + "/cancel").c_str())->status, 202);
  EXPECT_EQ(wait_finished(c, a, 60), "cancelled");
  EXPECT_EQ(wait_finished(c, b, 60), "cancelled");
  EXPECT_EQ(wait_finished(c, k, 60), "done");
  const json kt = body(c.Get(("/api/v1/trials/" + k).c_str()));
  EXPECT_EQ(kt["stages"][1]["state"], "skipped");  // only IK was asked for
  const json list = body(c.Get("/api/v1/trials?status=cancelled&limit=1"));
  EXPECT_EQ(list["total"], 2);
  EXPECT_EQ(list["trials"].size(), 1u);
  const std::string metrics = c.Get("/metrics")->body;
  EXPECT_NE(metrics.find("cpgait_trials{status=\"cancelled\"} 2"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cpgait_stage_seconds_count{stage=\"ik\"}"), std::string::npos) << metrics;
  EXPECT_EQ(c.Delete(("/api/v1/trials/" + k).c_str())->status, 204);
  EXPECT_EQ(c.Get(("/api/v1/trials/" + k).c_str())->status, 404);
  EXPECT_FALSE(fs::exists(dir + "/data/trials/" + k));
  // One log line per request and per stage, with the trial id.
  EXPECT_NE(server.log().find("\"event\":\"stage\""), std::string::npos);
  EXPECT_NE(server.log().find("\"trial\":\"" + k + "\""), std::string::npos);
  fs::remove_all(dir);
}

// Acceptance 4: 50 concurrent uploads of subject01 all complete; wall time, peak memory and the
// latency of GET /trials/{id} while they run are reported.
TEST(ApiReference, FiftyConcurrentUploads) {
  const std::string pl = cpgait::refdata::gait2392("pipeline/");
  for (const auto& f : {"OutputReference/subject01_simbody.osim", "subject01_walk1.trc", "subject01_walk1_grf.mot"}) REQUIRE_REFERENCE(pl + f);
  const std::string dir = cpgait::refdata::temp_dir("api_load");
  ServerProcess server(dir + "/data", {"--workers", "2"});
  httplib::Client c("127.0.0.1", server.port());
  auto m = c.Post("/api/v1/models", httplib::MultipartFormDataItems{
                                        {"model", slurp(pl + "OutputReference/subject01_simbody.osim"), "subject01_simbody.osim", ""}});
  ASSERT_EQ(m->status, 201);
  // Service throughput on IK, ID and SO (the CPG fit costs seconds a trial and has its own benchmark).
  const json options = {{"model", body(m)["id"]}, {"time_range", {0.5, 2.5}}, {"stages", {"ik", "id", "so"}}};
  httplib::MultipartFormDataItems form = trial_form(slurp(pl + "subject01_walk1.trc"), "subject01_walk1.trc", options);
  form.push_back({"grf", slurp(pl + "subject01_walk1_grf.mot"), "subject01_walk1_grf.mot", ""});
  form.push_back({"loads", slurp(pl + "subject01_walk1_grf.xml"), "subject01_walk1_grf.xml", ""});

  const auto start = std::chrono::steady_clock::now();
  std::vector<std::string> ids(50), failures(50);
  std::vector<std::thread> uploaders;
  for (int i = 0; i < 50; ++i)
    uploaders.emplace_back([&, i] {
      httplib::Client ci("127.0.0.1", server.port());
      ci.set_read_timeout(60, 0);
      ci.set_write_timeout(60, 0);
      ci.set_connection_timeout(10, 0);
      auto r = ci.Post("/api/v1/trials", form);
      if (r && r->status == 202) ids[i] = json::parse(r->body)["id"];
      else failures[i] = r ? std::to_string(r->status) + " " + r->body : "transport error " + httplib::to_string(r.error());
    });
  for (auto& t : uploaders) t.join();
  for (const auto& f : failures) EXPECT_TRUE(f.empty()) << f;
  ASSERT_EQ(std::count_if(ids.begin(), ids.end(), [](const std::string& s) { return !s.empty(); }), 50);
  // Poll every trial while they run; keep the latencies. The bound is liveness only (measured ~10 s
  // for all 50 here; throughput is measured by the benchmark BM_PipelineIkIdSoSubject01).
  std::vector<double> latency_ms;
  int done = 0;
  const auto liveness = start + std::chrono::seconds(900);
  while (done < 50 && std::chrono::steady_clock::now() < liveness) {
    done = 0;
    for (const auto& id : ids) {
      const auto t0 = std::chrono::steady_clock::now();
      auto r = c.Get(("/api/v1/trials/" + id).c_str());
      latency_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      ASSERT_TRUE(r && r->status == 200);
      const std::string s = json::parse(r->body)["status"];
      ASSERT_NE(s, "failed") << r->body;
      done += s == "done";
    }
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(done, 50) << "trials still unfinished after the 900 s liveness bound";
  std::sort(latency_ms.begin(), latency_ms.end());
  long peak_kb = 0;
  {
    std::ifstream status("/proc/" + std::to_string(server.pid()) + "/status");
    std::string line;
    while (std::getline(status, line))
      if (line.rfind("VmHWM:", 0) == 0) peak_kb = std::stol(line.substr(6));
  }
  std::printf("[ info ] not asserted (timings, for the record; the benchmark holds throughput): 50 concurrent subject01 uploads "
              "(2 workers): all done in %.2f s; server peak RSS %.1f MB; GET /trials/{id} while running: p50 %.2f ms, p95 %.2f ms over %zu requests\n",
              wall, peak_kb / 1024.0, latency_ms[latency_ms.size() / 2], latency_ms[latency_ms.size() * 95 / 100], latency_ms.size());
  fs::remove_all(dir);
}

// AprilTag footage as a trial's input: videos + calibration + tag set upload, a capture stage makes
// the markers, IK runs on them; bad footage inputs are refused naming the part.
TEST(Api, FootageUploadRunsCaptureThenIk) {
  const std::string dir = cpgait::refdata::temp_dir("api_footage");
  cpgait::fixtures::FootageOptions fo;
  fo.duration_s = 0.5;
  fo.rate_hz = 30;
  const auto wf = cpgait::fixtures::render_walk_footage(dir + "/footage", fo);
  ServerProcess server(dir + "/data");
  httplib::Client c("127.0.0.1", server.port());
  c.set_read_timeout(120, 0);
  auto form = [&](const std::vector<std::string>& videos, const std::string& calibration, const std::string& tags) {
    httplib::MultipartFormDataItems f;
    for (const auto& v : videos) f.push_back({"videos", slurp(v), fs::path(v).filename().string(), "video/x-msvideo"});
    f.push_back({"calibration", calibration, "calibration.json", "application/json"});
    f.push_back({"tags", tags, "tags.json", "application/json"});
    f.push_back({"options", json{{"model", "walker"}, {"stages", {"ik"}}}.dump(), "options.json", "application/json"});
    return f;
  };
  const std::string calibration = slurp(wf.calibration_path), tags = slurp(wf.tags_path);
  auto r = c.Post("/api/v1/trials", form(wf.videos, calibration, tags));
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = body(r)["id"];
  ASSERT_EQ(wait_finished(c, id, 120), "done") << server.log();
  const json t = body(c.Get(("/api/v1/trials/" + id).c_str()));
  ASSERT_EQ(t["stages"][0]["name"], "capture");
  EXPECT_EQ(t["stages"][0]["state"], "done");
  EXPECT_GT(t["stages"][0]["summary"]["corners_triangulated"].get<int>(), 500);
  EXPECT_EQ(t["stages"][1]["name"], "ik");
  EXPECT_EQ(t["stages"][1]["state"], "done");
  EXPECT_LT(t["stages"][1]["summary"]["marker_rms_mean_m"].get<double>(), 0.002);
  for (const char* f : {"capture.trc", "capture_capture_quality.sto", "capture_tag_markers.xml", "capture_ik.mot"})
    EXPECT_EQ(c.Get(("/api/v1/trials/" + id + "/files/" + f).c_str())->status, 200) << f;
  const auto k = c.Get(("/api/v1/trials/" + id + "/kinematics").c_str());
  ASSERT_EQ(k->status, 200) << k->body;
  EXPECT_EQ(body(k)["measured_marker_names"].size(), 4 * cpgait::fixtures::tagged_walker().tags.tags.size());

  // Bad footage inputs: 4xx naming the part, nothing stored.
  const auto before = body(c.Get("/api/v1/trials"))["total"].get<int>();
  auto err = [&](const httplib::Result& res) {
    const json e = body(res)["error"];
    return std::make_pair(res->status, e.value("part", e.value("field", std::string())));
  };
  std::vector<std::string> renamed = wf.videos;
  fs::copy_file(wf.videos[0], dir + "/cam9.avi");
  renamed[0] = dir + "/cam9.avi";
  EXPECT_EQ(err(c.Post("/api/v1/trials", form(renamed, calibration, tags))), std::make_pair(422, std::string("videos")));
  { std::ofstream(dir + "/cam0.avi") << "not a video"; }
  std::vector<std::string> broken = wf.videos;
  broken[0] = dir + "/cam0.avi";
  EXPECT_EQ(err(c.Post("/api/v1/trials", form(broken, calibration, tags))), std::make_pair(422, std::string("videos")));
  EXPECT_EQ(err(c.Post("/api/v1/trials", form(wf.videos, calibration, "{\"tags\": [{\"id\": 1}]}"))).second, "tags");
  EXPECT_EQ(err(c.Post("/api/v1/trials", form(wf.videos, "{\"cameras\": 3", tags))).second, "calibration");
  httplib::MultipartFormDataItems no_tags = form(wf.videos, calibration, tags);
  no_tags.erase(std::remove_if(no_tags.begin(), no_tags.end(), [](const auto& i) { return i.name == "tags"; }), no_tags.end());
  EXPECT_EQ(err(c.Post("/api/v1/trials", no_tags)), std::make_pair(400, std::string("tags")));
  EXPECT_EQ(body(c.Get("/api/v1/trials"))["total"].get<int>(), before);
  fs::remove_all(dir);
}
