// The pipeline as a table of stages (issue 17): every option read, written and published from one
// description; unknown or mistyped fields refused by path; a stage added by its own file and one
// table line; job.json kept from before the table reruns to the same bytes.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/progress.h"
#include "json_schema_check.h"
#include "pipeline.h"
#include "stages/products.h"
#include "test_support.h"

namespace fs = std::filesystem;
using cpgait::InputError;
using nlohmann::json;
using namespace cpgait::services;

namespace {

// A value the field's schema accepts that differs from its default.
json other_valid_value(const json& field) {
  if (field.contains("enum")) {
    for (const auto& v : field["enum"])
      if (!field.contains("default") || v != field["default"]) return v;
  }
  const std::string type = field.value("type", "");
  if (type == "boolean") return !field.value("default", false);
  if (type == "integer") return field.contains("default") && field["default"] == field["maximum"] ? field["minimum"] : field["maximum"];
  if (type == "number") {
    const double lo = field.contains("minimum") ? field["minimum"].get<double>() : field.value("exclusiveMinimum", 0.0);
    const double hi = field.contains("maximum") ? field["maximum"].get<double>() : lo + 10;
    return lo + 0.37 * (hi - lo);
  }
  if (type == "string") return "calcn_l";
  if (type == "array" && field.contains("items")) {
    json a = json::array();  // two items, or two groups of x-group (a list of vectors' components)
    for (int i = 0; i < 2 * field.value("x-group", 1); ++i) a.push_back(other_valid_value(field["items"]));
    return a;
  }
  if (type == "object" && field.contains("additionalProperties") && field["additionalProperties"].value("type", "") == "array")
    return {{"pelvis", {1.1, 1.05, 0.95}}};  // a map of triples (scale.factors)
  if (type == "object") return {{"markers", {{"R.ASIS", 4}}}};
  return nullptr;
}

// A value of the wrong type for the field.
json mistyped_value(const json& field) {
  const std::string type = field.value("type", "");
  if (type == "string") return 7;
  if (type == "boolean") return "yes";
  return "not a " + type;
}

// Every stage field of the schema: (stage, key, field schema).
std::vector<std::tuple<std::string, std::string, json>> stage_fields(const json& schema) {
  std::vector<std::tuple<std::string, std::string, json>> out;
  for (const Stage* s : pipeline_stages())
    for (const auto& [key, field] : schema["properties"][s->name()]["properties"].items()) out.emplace_back(s->name(), key, field);
  return out;
}

InputError refusal(const json& doc, const StageTable& table = pipeline_stages()) {
  try {
    PipelineOptions::from_json(doc, "options.json", table);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "accepted " << doc.dump();
  return InputError("", 0, "", "");
}

}  // namespace

TEST(PipelineOptions, EveryFieldOfTheSchemaRoundTripsWithANonDefaultValue) {
  const json schema = pipeline_options_schema();
  json doc = {{"model", "m1"},
              {"scale_muscles_from", "g1"},
              {"activation", "cmc"},
              {"stages", {"ik", "id"}},
              {"time_range", {0.25, 1.5}},
              {"inputs", {{"model", "/x.osim"}}}};
  int fields = 0;
  for (const auto& [stage, key, field] : stage_fields(schema)) {
    doc[stage][key] = other_valid_value(field);
    ASSERT_FALSE(doc[stage][key].is_null()) << stage << "." << key;
    if (field.contains("default")) {
      EXPECT_NE(doc[stage][key], field["default"]) << stage << "." << key;
    }
    ++fields;
  }
  EXPECT_GE(fields, 26);  // scale 5, capture 5, ik 2, id 1, so 3, cmc 5, cpg 3, gait 2
  const PipelineOptions o = PipelineOptions::from_json(doc, "options.json");
  EXPECT_EQ(o.to_json(), doc);
  EXPECT_TRUE(cpgait::testing::schema_violations(schema, doc).empty());
  // Defaults: every stage's object is written complete and matches the schema's defaults.
  const json defaults = PipelineOptions().to_json();
  for (const Stage* s : pipeline_stages()) EXPECT_EQ(defaults[s->name()], schema["properties"][s->name()]["default"]) << s->name();
  EXPECT_TRUE(cpgait::testing::schema_violations(schema, defaults).empty());
}

TEST(PipelineOptions, UnknownOrMistypedFieldsAreRefusedNamingTheirPath) {
  const json schema = pipeline_options_schema();
  for (const auto& [stage, key, field] : stage_fields(schema)) {
    const json bad = {{stage, {{key, mistyped_value(field)}}}};
    EXPECT_FALSE(cpgait::testing::schema_violations(schema, bad).empty()) << bad.dump();
    const InputError e = refusal(bad);
    EXPECT_EQ(e.field(), stage + "." + key) << e.what();
    EXPECT_EQ(e.file(), "options.json");
    const InputError unknown = refusal({{stage, {{key + "_typo", 1}}}});
    EXPECT_EQ(unknown.field(), stage + "." + key + "_typo");
    EXPECT_NE(std::string(unknown.what()).find(key), std::string::npos) << "the message lists the known keys: " << unknown.what();
  }
  EXPECT_EQ(refusal({{"stagez", {"ik"}}}).field(), "stagez");
  EXPECT_EQ(refusal({{"gait", "fast"}}).field(), "gait");
  EXPECT_EQ(refusal({{"stages", {"ik", "warp"}}}).field(), "stages");
  EXPECT_EQ(refusal({{"time_range", {2, 1}}}).field(), "time_range");
  EXPECT_EQ(refusal({{"cpg", {{"pairs", 2.5}}}}).field(), "cpg.pairs");
  EXPECT_EQ(refusal({{"cpg", {{"pairs", 7}}}}).field(), "cpg.pairs");
  EXPECT_EQ(refusal({{"gait", {{"duration_s", 0}}}}).field(), "gait.duration_s");
  EXPECT_EQ(refusal({{"ik", {{"tasks", {{"coordinates", {{"x", {{"value_type", "guess"}}}}}}}}}}).field().rfind("ik.tasks", 0), 0u);
  const InputError needs = refusal({{"stages", {"ik", "cpg"}}});
  EXPECT_EQ(needs.field(), "stages");
  EXPECT_NE(needs.message().find("'cpg' needs 'so'"), std::string::npos) << needs.message();
  // The activation picks which stage the CPG builds on.
  EXPECT_EQ(refusal({{"activation", "emg"}}).field(), "activation");
  const InputError cmc_needed = refusal({{"activation", "cmc"}, {"stages", {"ik", "so", "cpg"}}});
  EXPECT_NE(cmc_needed.message().find("'cpg' needs 'cmc' (the activation)"), std::string::npos) << cmc_needed.message();
  const PipelineOptions cmc = PipelineOptions::from_json({{"activation", "cmc"}, {"stages", {"ik", "cmc", "cpg"}}}, "options.json");
  TrialInputs in;
  EXPECT_TRUE(cmc.runs(*find_stage("cmc"), in));
  EXPECT_FALSE(PipelineOptions().runs(*find_stage("cmc"), in));  // listed by default, but so is the activation
  EXPECT_TRUE(PipelineOptions().runs(*find_stage("so"), in));
}

TEST(PipelineOptions, StagesListTheirNeedsAndFilesInRunOrder) {
  const json stages = pipeline_stages_json();
  std::vector<std::string> names;
  for (const auto& s : stages) {
    names.push_back(s["name"]);
    for (const auto& need : s["needs"]) {  // a stage runs after what it needs ("activation": so or cmc)
      for (const std::string& n : need == "activation" ? std::vector<std::string>{"so", "cmc"} : std::vector<std::string>{need.get<std::string>()})
        EXPECT_NE(std::find(names.begin(), names.end() - 1, n), names.end() - 1) << s.dump();
    }
    for (const auto& t : s["tables"])  // tables served by the results endpoint are files it writes
      EXPECT_NE(std::find(s["writes"].begin(), s["writes"].end(), t), s["writes"].end()) << s.dump();
  }
  EXPECT_EQ(names, (std::vector<std::string>{"scale", "capture", "ik", "id", "so", "cmc", "cpg", "gait"}));
  EXPECT_FALSE(stages[0]["selectable"].get<bool>());
  EXPECT_FALSE(stages[1]["selectable"].get<bool>());
  EXPECT_EQ(pipeline_options_schema()["properties"]["stages"]["items"]["enum"], json({"ik", "id", "so", "cmc", "cpg", "gait"}));
  EXPECT_EQ(pipeline_options_schema()["properties"]["activation"]["enum"], json({"so", "cmc"}));
  EXPECT_EQ(PipelineOptions().activation, "so");
}

namespace {

// A stage that only a test knows: it scales the IK coordinates by its gain and writes them.
struct EchoOptions {
  double gain = 2.0;
  static const OptionFields<EchoOptions>& fields() {
    static const OptionFields<EchoOptions> f =
        OptionFields<EchoOptions>("A test stage.")
            .number("gain", &EchoOptions::gain, "", "factor on the IK coordinates", NumberRange{0.0, 10.0});
    return f;
  }
};

class EchoStage final : public StageWithOptions<EchoOptions> {
 public:
  std::string name() const override { return "echo"; }
  std::string description() const override { return "test stage: IK coordinates times a gain"; }
  std::vector<std::string> needs() const override { return {"ik"}; }
  std::vector<std::string> writes() const override { return {"_echo.sto"}; }
  std::vector<std::string> tables() const override { return writes(); }

 protected:
  json execute(StageContext& trial, const EchoOptions& o) const override {
    cpgait::Storage s = trial.products.find<IkProduct>()->coordinates;
    s.data.rightCols(s.num_columns() - 1) *= o.gain;
    trial.write(s, "_echo.sto");
    return {{"gain", o.gain}, {"rows", s.num_rows()}};
  }
};

struct RecordingObserver : PipelineObserver {
  std::vector<std::string> events;
  bool cancel = false;
  void stage_started(const std::string& s) override { events.push_back("start " + s); }
  void stage_finished(const std::string& s, double, const json&) override { events.push_back("finish " + s); }
  bool cancelled() const override { return cancel; }
};

TrialInputs walker_trial(const std::string& dir, double duration_s = 0.5) {
  cpgait::fixtures::SyntheticTrialOptions so;
  so.duration_s = duration_s;
  const auto trial = cpgait::fixtures::synthesize_trial(cpgait::refdata::walker(), so);
  TrialInputs in;
  in.name = "walk";
  in.model_path = cpgait::refdata::fixture("models/walker.osim");
  in.markers = cpgait::format_trc(trial.markers, "mm");
  in.markers_name = dir + "/walk.trc";
  return in;
}

}  // namespace

// A stage of several long steps (the gait stage's tunings at each knob, then its walks) reports each
// as a share of its own progress, so the stage's rises through all of them; cancelling reaches each.
TEST(PipelineStages, AStepsProgressIsItsShareOfTheStages) {
  struct Recording : cpgait::Progress {
    std::vector<double> fractions;
    bool cancel = false;
    void report(double fraction, std::string_view) override { fractions.push_back(fraction); }
    bool cancelled() const override { return cancel; }
  } stage;
  cpgait::ProgressShare first(&stage, 0.0, 0.6), second(&stage, 0.6, 0.95);
  first.report(0.5, "tuning");
  first.report(1.0, "tuning");
  second.report(0.5, "tuning");
  ASSERT_EQ(stage.fractions.size(), 3u);
  EXPECT_DOUBLE_EQ(stage.fractions[0], 0.3);
  EXPECT_DOUBLE_EQ(stage.fractions[1], 0.6);
  EXPECT_DOUBLE_EQ(stage.fractions[2], 0.775);
  EXPECT_FALSE(second.cancelled());
  stage.cancel = true;
  EXPECT_TRUE(second.cancelled());
  cpgait::ProgressShare orphan(nullptr, 0.0, 1.0);
  orphan.report(0.5, "nobody listens");
  EXPECT_FALSE(orphan.cancelled());
}

// The gait stage's walks (untuned here: its main walk, the two check tolerances' and speed knob 0.8's)
// each take a quarter of its progress: the main walk reports up to a quarter, the rest comes after
// its motion was written. (Before, the main walk took the bar to 100 % and the others reported nothing.)
TEST(PipelineStages, TheGaitStagesWalksEachReportTheirShareOfItsProgress) {
  const std::string dir = cpgait::refdata::temp_dir("gait_progress");
  const TrialInputs in = walker_trial(dir, 4.0);
  struct GaitProgress : PipelineObserver {
    std::string main_walk;
    std::vector<std::pair<double, bool>> reports;  // the fraction, and whether the main walk was written by then
    void stage_progress(const std::string& stage, double fraction) override {
      if (stage == "gait") reports.emplace_back(fraction, fs::exists(main_walk));
    }
  } observer;
  observer.main_walk = dir + "/out/walk_gait.mot";
  const PipelineOptions o = PipelineOptions::from_json(
      {{"gait", {{"tune_evaluations", 0}, {"foot_spheres", 2}, {"speed_knobs", {0.8}}, {"check_tolerances", {5e-4, 2e-3}}}}}, "options.json");
  run_pipeline(in, o, dir + "/out", &observer);
  ASSERT_FALSE(observer.reports.empty());
  bool after_main_walk = false;
  for (std::size_t i = 0; i < observer.reports.size(); ++i) {
    const auto [fraction, written] = observer.reports[i];
    if (written) {
      EXPECT_GE(fraction, 0.25 - 1e-12) << "report " << i;
    } else {
      EXPECT_LE(fraction, 0.25 + 1e-12) << "report " << i;
    }
    if (i > 0) {
      EXPECT_GE(fraction, observer.reports[i - 1].first) << "report " << i;
    }
    after_main_walk = after_main_walk || (written && fraction > 0.7);
  }
  EXPECT_TRUE(after_main_walk) << "no progress from the speed knob's walk";
  fs::remove_all(dir);
}

TEST(PipelineStages, ATestStageIsItsOwnFileAndOneTableLine) {
  static const EchoStage echo;
  StageTable table = pipeline_stages();
  table.push_back(&echo);  // the one line

  const PipelineOptions o = PipelineOptions::from_json({{"stages", {"ik", "echo"}}, {"echo", {{"gain", 3}}}}, "options.json", table);
  EXPECT_EQ(o.to_json()["echo"], json({{"gain", 3.0}}));
  EXPECT_EQ(refusal({{"stages", {"echo"}}}, table).message(), "stage 'echo' needs 'ik'");
  EXPECT_EQ(refusal({{"echo", {{"gian", 1}}}}, table).field(), "echo.gian");
  EXPECT_EQ(refusal({{"echo", {{"gain", 11}}}}, table).field(), "echo.gain");
  const json schema = pipeline_options_schema(table);
  EXPECT_EQ(schema["properties"]["echo"]["properties"]["gain"]["default"], 2.0);
  EXPECT_NE(
      std::find(schema["properties"]["stages"]["items"]["enum"].begin(), schema["properties"]["stages"]["items"]["enum"].end(), "echo"),
      schema["properties"]["stages"]["items"]["enum"].end());
  EXPECT_EQ(pipeline_stages_json(table).back()["needs"], json({"ik"}));

  const std::string dir = cpgait::refdata::temp_dir("echo_stage");
  const TrialInputs in = walker_trial(dir);
  validate_inputs(in, o);
  RecordingObserver observer;
  const PipelineResult r = run_pipeline(in, o, dir + "/out", &observer);
  EXPECT_EQ(observer.events, (std::vector<std::string>{"start ik", "finish ik", "start echo", "finish echo"}));
  EXPECT_EQ(r.files, (std::vector<std::string>{"walk_ik.mot", "walk_ik_marker_errors.sto", "walk_echo.sto", "job.json"}));
  EXPECT_EQ(r.summary["echo"]["gain"], 3.0);
  const cpgait::Storage ik = cpgait::read_storage(dir + "/out/walk_ik.mot"), scaled = cpgait::read_storage(dir + "/out/walk_echo.sto");
  ASSERT_EQ(scaled.num_rows(), ik.num_rows());
  ASSERT_GT(ik.num_rows(), 10);
  EXPECT_NEAR((scaled.data.rightCols(ik.num_columns() - 1) - 3.0 * ik.data.rightCols(ik.num_columns() - 1)).cwiseAbs().maxCoeff(), 0.0,
              1e-5);
  // job.json reads back with the same table only.
  const json job = json::parse(cpgait::text::read_file(dir + "/out/job.json"));
  EXPECT_EQ(PipelineOptions::from_json(job, "job.json", table).to_json(), job);
  EXPECT_EQ(refusal(job).field(), "echo");
}

TEST(PipelineStages, CancellationStopsBeforeTheNextStageAndWritesNoJobJson) {
  const std::string dir = cpgait::refdata::temp_dir("cancel_stage");
  const TrialInputs in = walker_trial(dir);
  RecordingObserver observer;
  observer.cancel = true;
  EXPECT_THROW(run_pipeline(in, PipelineOptions(), dir + "/out", &observer), std::runtime_error);
  EXPECT_TRUE(observer.events.empty());
  EXPECT_FALSE(fs::exists(dir + "/out/job.json"));
}

namespace {
using cpgait::refdata::CliRun;
CliRun cli(const std::string& args) { return cpgait::refdata::run_cpgait(args); }
json without_inputs(json j) {
  j.erase("inputs");
  return j;
}
}  // namespace

// tests/services/kept/job_before_stage_table.json was written by `cpgait run` before the stage table
// (commit cdbca5f) with a non-default value in every field; only its absolute input paths were
// removed. Rerun, it must write the same job.json, and that job.json the same files again.
TEST(PipelineStages, AJobJsonFromBeforeTheStageTableRerunsToTheSameBytes) {
  const std::string kept_path = std::string(CPGAIT_SOURCE_DIR) + "/tests/services/kept/job_before_stage_table.json";
  const std::string kept = cpgait::text::read_file(kept_path);
  const std::string dir = cpgait::refdata::temp_dir("kept_job");
  const TrialInputs in = walker_trial(dir);
  std::ofstream(dir + "/walk.trc") << in.markers;
  const CliRun a = cli("run --options " + kept_path + " --model " + in.model_path + " --markers " + dir + "/walk.trc -o " + dir + "/a");
  ASSERT_EQ(a.status, 0) << a.output;
  const std::string written = cpgait::text::read_file(dir + "/a/job.json");
  // The scale and cmc stages and the activation choice came later: their sections are their defaults
  // (scale does not run without a static trial, cmc only with "activation": "cmc").
  json written_doc = without_inputs(json::parse(written));
  for (const char* later : {"scale", "cmc", "activation"}) {
    EXPECT_EQ(written_doc[later], PipelineOptions().to_json()[later]) << later;
    written_doc.erase(later);
  }
  // Fields added to a section since: their defaults.
  for (const auto& [section, field] : {std::pair<const char*, const char*>{"gait", "phase_reference"}, {"gait", "tune_evaluations"},
                                       {"gait", "tune_horizon_s"}, {"gait", "tune_rounds"}, {"gait", "speed_knobs"},
                                       {"gait", "schedule_evaluations"}, {"gait", "tune_rotation_limit_deg"},
                                       {"gait", "tune_steps_m"}, {"gait", "tune_pushes_N_s"}, {"gait", "tune_tolerances"}, {"gait", "tune_step_at"},
                                       {"gait", "check_tolerances"}, {"gait", "foot_spheres"}, {"gait", "tolerance"},
                                       {"gait", "control_interval_s"}, {"gait", "tune_entrainment"}, {"gait", "integrator"},
                                       {"gait", "tune_stop_at"}, {"gait", "tune_population"}, {"gait", "tune_restarts"}, {"gait", "tune_seed"},
                                       {"gait", "schedule_step_decay"}, {"gait", "tune_budget_simulated_s"},
                                       {"gait", "tune_drift_weight"}, {"gait", "gain_margin"}, {"gait", "tune_swing_world"},
                                       {"gait", "tune_stance_hold"}, {"gait", "tune_cycle_weight"}, {"gait", "tune_ankle"}}) {
    EXPECT_EQ(written_doc[section][field], PipelineOptions().to_json()[section][field]) << section << "." << field;
    written_doc[section].erase(field);
  }
  EXPECT_EQ(written_doc.dump(2), without_inputs(json::parse(kept)).dump(2));
  EXPECT_EQ(json::parse(written)["inputs"]["markers"], dir + "/walk.trc");
  const CliRun b = cli("run --options " + dir + "/a/job.json -o " + dir + "/b");
  ASSERT_EQ(b.status, 0) << b.output;
  int compared = 0;
  for (const auto& e : fs::directory_iterator(dir + "/a")) {
    EXPECT_EQ(cpgait::text::read_file(e.path().string()), cpgait::text::read_file(dir + "/b/" + e.path().filename().string()))
        << e.path().filename();
    ++compared;
  }
  EXPECT_EQ(compared, 6);  // ik (2), id, so (2), job.json
}

TEST(PipelineStages, TheCliPublishesTheSchemaAndEveryJobJsonItWritesConformsToIt) {
  const CliRun s = cli("run --print-options-schema");
  ASSERT_EQ(s.status, 0) << s.output;
  const json schema = json::parse(s.output);
  EXPECT_EQ(schema, pipeline_options_schema());
  const std::string dir = cpgait::refdata::temp_dir("schema_cli");
  const TrialInputs in = walker_trial(dir);
  std::ofstream(dir + "/walk.trc") << in.markers;
  std::ofstream(dir + "/o.json") << json({{"stages", {"ik"}}, {"gait", {{"duration_s", 1.5}}}}).dump();
  const CliRun r = cli("run --options " + dir + "/o.json --model " + in.model_path + " --markers " + dir + "/walk.trc -o " + dir + "/out");
  ASSERT_EQ(r.status, 0) << r.output;
  const json job = json::parse(cpgait::text::read_file(dir + "/out/job.json"));
  const auto violations = cpgait::testing::schema_violations(schema, job);
  EXPECT_TRUE(violations.empty()) << violations.front();
  // A mistyped option is refused by the CLI naming its path.
  std::ofstream(dir + "/bad.json") << json({{"so", {{"activation_exponent", "two"}}}}).dump();
  const CliRun bad =
      cli("run --options " + dir + "/bad.json --model " + in.model_path + " --markers " + dir + "/walk.trc -o " + dir + "/bad");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.output.find("bad.json: so.activation_exponent: expected a number"), std::string::npos) << bad.output;
}
