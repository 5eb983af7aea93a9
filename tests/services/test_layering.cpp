// Layers point one way: capture -> solver -> services -> web. capture/ produces recordings (markers,
// forces, tag corners) and reads OpenSim's documents; what needs a model lives in solver/.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "cpgait/capture/text_lines.h"

namespace fs = std::filesystem;

TEST(Layering, CaptureIncludesOnlyItsOwnHeaders) {
  const fs::path root = fs::path(CPGAIT_SOURCE_DIR) / "capture";
  const std::regex include(R"re(^\s*#\s*include\s*"(cpgait/[^"]+)")re");
  int files = 0, includes = 0;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    const std::string ext = e.path().extension().string();
    if (ext != ".h" && ext != ".cpp") continue;
    ++files;
    std::ifstream in(e.path());
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      std::smatch m;
      if (!std::regex_search(line, m, include)) continue;
      ++includes;
      EXPECT_TRUE(fs::exists(root / "include" / m[1].str()))
          << e.path().string() << ":" << n << " includes " << m[1] << ", which capture/ does not hold (a layer above it)";
    }
  }
  EXPECT_GT(files, 40);
  EXPECT_GT(includes, 100);
  // And its libraries link nothing above them.
  const std::string cmake = cpgait::text::read_file((root / "CMakeLists.txt").string());
  for (const char* above : {"cpgait_solver", "cpgait_services", "cpgait_tags", "cpgait_fixtures"})
    EXPECT_EQ(cmake.find(std::string("PUBLIC ") + above), std::string::npos) << above;
  EXPECT_EQ(cmake.find("cpgait_solver"), std::string::npos);
}
