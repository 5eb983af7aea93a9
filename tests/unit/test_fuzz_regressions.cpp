// The fuzzing targets' inputs replayed in the suite (seconds): every input kept under
// tests/fuzz/regressions/<target>/ (what scripts/fuzz.sh found, fixed) and inputs made by code for
// each target go through the same entry the libFuzzer targets use; only InputError may come out.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <sstream>

#include "cpgait/capture/text_lines.h"
#include "fuzz/fuzz_targets.h"
#include "test_support.h"

using namespace cpgait;

TEST(FuzzRegressions, EveryKeptInputIsReadOrRefused) {
  const std::map<std::string, std::vector<std::string>> made = cpgait::testing::fuzz_made_inputs();
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
  EXPECT_GE(inputs, 30);
}

// scripts/fuzz.sh builds the targets CMake lists; each must be one fuzz_one knows, with made inputs.
TEST(FuzzRegressions, CMakeListsEveryTarget) {
  std::vector<std::string> listed;
  std::stringstream names(CPGAIT_FUZZ_TARGETS);
  for (std::string name; std::getline(names, name, ',');) listed.push_back(name);
  EXPECT_EQ(listed, cpgait::testing::fuzz_target_names());
  const auto made = cpgait::testing::fuzz_made_inputs();
  for (const std::string& target : listed) EXPECT_TRUE(made.count(target) && !made.at(target).empty()) << target;
}
