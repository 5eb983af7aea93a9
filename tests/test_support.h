#pragma once
// Where tests find OpenSim's reference data (../shared) and cpgait's fixtures. Tests that need the
// reference data skip with a message naming the missing path.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace cpgait::refdata {

inline std::string shared_path(const std::string& relative) {
  return (std::filesystem::path(CPGAIT_SHARED_DIR) / "reference" / relative).lexically_normal().string();
}
inline std::string gait2392(const std::string& relative) { return shared_path("opensim/gait2392/" + relative); }
inline std::string fixture(const std::string& relative) {
  return std::string(CPGAIT_FIXTURES_DIR) + "/" + relative;
}

}  // namespace cpgait::refdata

// Skips the test when a reference file is absent.
#define REQUIRE_REFERENCE(path)                                                                   \
  do {                                                                                            \
    if (!std::filesystem::exists(path))                                                           \
      GTEST_SKIP() << "reference data absent: " << (path) << " (../shared/reference not present)"; \
  } while (0)
