// The fuzzing targets' inputs replayed in the suite (seconds): every input kept under
// tests/fuzz/regressions/<target>/ (what scripts/fuzz.sh found, fixed) and inputs made by code for
// each target go through the same entry the libFuzzer targets use; only InputError may come out.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>

#include "c3d_writer.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "fuzz/fuzz_targets.h"
#include "test_support.h"

using namespace cpgait;

TEST(FuzzRegressions, EveryKeptInputIsReadOrRefused) {
  const MarkerTrial trial = fixtures::synthesize_trial(refdata::walker(), {}).markers;
  const std::map<std::string, std::vector<std::string>> made = {
      {"trc", {format_trc(trial, "mm"), "PathFileType\t4\n"}},
      {"storage", {"x\nversion=1\nnRows=1\nnColumns=2\nendheader\ntime\ta\n0\t1\n", "endheader\n"}},
      {"c3d", {cpgait::testing::format_c3d_z_up(trial), std::string(512, '\0')}},
      {"osim", {text::read_file(refdata::fixture("models/walker.osim")), "<Model>"}},
      {"external_loads", {"<ExternalLoads><objects><ExternalForce/></objects></ExternalLoads>"}},
      {"ik_tasks_json", {R"({"markers": {"R.ASIS": 2}})", "{"}},
      {"scale_setup", {"<OpenSimDocument><ScaleTool><mass>-5</mass></ScaleTool></OpenSimDocument>"}}};
  const std::filesystem::path kept = std::filesystem::path(CPGAIT_SOURCE_DIR) / "tests/fuzz/regressions";
  int inputs = 0;
  for (const std::string& target : cpgait::testing::fuzz_target_names()) {
    std::vector<std::string> all = made.at(target);
    if (std::filesystem::is_directory(kept / target))
      for (const auto& e : std::filesystem::directory_iterator(kept / target)) all.push_back(text::read_file(e.path().string()));
    for (const std::string& bytes : all) {
      try {
        cpgait::testing::fuzz_one(target, bytes);
      } catch (const std::exception& e) {
        ADD_FAILURE() << target << ": " << e.what();
      }
      ++inputs;
    }
  }
  EXPECT_GE(inputs, 12);
}
