// Layers point one way: capture -> solver -> services -> web. capture/ produces recordings (markers,
// forces, tag corners) and reads OpenSim's documents; what needs a model lives in solver/.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
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

// The command line starts fast because it does not link the video libraries: OpenCV (with its
// codecs, FFmpeg, GStreamer...) and AprilTag are in build/libcpgait_footage.so, loaded when footage
// is used. The loader lists what the executable needs before main() runs.
TEST(Layering, CommandLineLinksNoVideoLibraries) {
  const std::string cmd = std::string("LD_TRACE_LOADED_OBJECTS=1 ") + CPGAIT_BINARY;
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[4096];
  while (fgets(buf, sizeof buf, p)) out += buf;
  pclose(p);
  int libraries = 0;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.find(".so") == std::string::npos) continue;
    ++libraries;
    EXPECT_EQ(line.find("opencv"), std::string::npos) << line;
    EXPECT_EQ(line.find("apriltag"), std::string::npos) << line;
  }
  EXPECT_GT(libraries, 5) << out;
  EXPECT_LT(libraries, 60) << "the executable loads " << libraries << " shared libraries:\n" << out;
  // The module is there, with the video libraries.
  const fs::path module = fs::path(CPGAIT_BINARY).parent_path() / "libcpgait_footage.so";
  EXPECT_TRUE(fs::exists(module)) << module;
}
