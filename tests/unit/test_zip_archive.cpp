// The ZIP reader a model upload with its Geometry folder goes through: archives made by Info-ZIP's
// `zip` (as labs make them: deflated, stored, streamed with data descriptors, with macOS resource
// forks) and by code, and the refusals, each naming the archive and the entry.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "test_support.h"
#include "zip_archive.h"
#include "zip_writer.h"

namespace fs = std::filesystem;
using cpgait::InputError;
using cpgait::services::read_zip;
using cpgait::services::ZipEntry;
using cpgait::testing::write_zip;

namespace {

std::string error_of(const std::string& bytes, cpgait::services::ZipReadOptions o = {}) {
  try {
    read_zip(bytes, "model.zip", o);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Runs Info-ZIP's zip in a folder holding a model and its Geometry folder; returns the archive.
std::string zip_tool(const std::string& dir, const std::string& flags) {
  const std::string out = dir + "/out.zip";
  fs::remove(out);
  const std::string cmd = "cd '" + dir + "/src' && zip -q -r " + flags + " '" + out + "' . > /dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0) return "";
  return cpgait::text::read_file(out);
}

}  // namespace

TEST(ZipArchive, ReadsWhatInfoZipWrites) {
  if (std::system("command -v zip > /dev/null 2>&1") != 0) GTEST_SKIP() << "Info-ZIP's zip is absent (./install-deps.sh installs it)";
  const std::string dir = cpgait::refdata::temp_dir("zip_tool");
  fs::create_directories(dir + "/src/Geometry");
  fs::create_directories(dir + "/src/__MACOSX/Geometry");
  const std::string osim = "<OpenSimDocument Version=\"40000\"/>\n";
  std::string femur;
  for (int i = 0; i < 2000; ++i) femur += "v 0." + std::to_string(i) + " 0 0\n";
  std::ofstream(dir + "/src/model.osim") << osim;
  std::ofstream(dir + "/src/Geometry/femur.obj") << femur;
  std::ofstream(dir + "/src/Geometry/empty.stl");
  std::ofstream(dir + "/src/__MACOSX/Geometry/._femur.obj") << "Mac OS X resource fork";
  std::ofstream(dir + "/src/Geometry/._femur.obj") << "AppleDouble";
  // Deflated (the default), stored (-0), streamed with data descriptors (-fd), with a comment (-z).
  for (const std::string flags : {"", "-0", "-fd", "-9 -X"}) {
    const std::string bytes = zip_tool(dir, flags);
    ASSERT_FALSE(bytes.empty()) << flags;
    const std::vector<ZipEntry> files = read_zip(bytes, "model.zip");
    std::map<std::string, std::string> by_path;
    for (const auto& f : files) by_path[f.path] = f.content;
    EXPECT_EQ(by_path.size(), 3u) << flags;  // no folders, no resource forks
    EXPECT_EQ(by_path["./model.osim"] + by_path["model.osim"], osim) << flags;
    EXPECT_EQ(by_path["./Geometry/femur.obj"] + by_path["Geometry/femur.obj"], femur) << flags;
    EXPECT_TRUE(by_path.count("Geometry/empty.stl") || by_path.count("./Geometry/empty.stl")) << flags;
  }
  // Refused, saying why: bzip2 entries, encrypted ones, ZIP64.
  EXPECT_NE(error_of(zip_tool(dir, "-Z bzip2")).find("compression method 12 is not supported"), std::string::npos) << error_of(zip_tool(dir, "-Z bzip2"));
  EXPECT_NE(error_of(zip_tool(dir, "-P secret")).find("encrypted entries are not supported"), std::string::npos);
  const std::string zip64 = zip_tool(dir, "-fz");
  ASSERT_FALSE(zip64.empty());
  EXPECT_NE(error_of(zip64).find("ZIP64"), std::string::npos) << error_of(zip64);
  fs::remove_all(dir);
}

TEST(ZipArchive, ReadsWhatCodeWritesAndRefusesBrokenArchives) {
  const std::string text(5000, 'x');
  const std::string good = write_zip({{"a/model.osim", "<doc/>", true, false},
                                      {"a\\Geometry\\bone.vtp", text, true, true},  // a Windows tool's separators
                                      {"a/Geometry/", "", false, false},
                                      {"b.txt", "stored", false, false}},
                                     "archive comment");
  const auto files = read_zip(good, "model.zip");
  ASSERT_EQ(files.size(), 3u);
  EXPECT_EQ(files[1].path, "a/Geometry/bone.vtp");
  EXPECT_EQ(files[1].content, text);
  EXPECT_EQ(files[2].content, "stored");

  EXPECT_NE(error_of("PK\x03\x04" + std::string(40, ' ')).find("no end-of-central-directory record"), std::string::npos);
  EXPECT_NE(error_of("short").find("shorter than its end record"), std::string::npos);
  // A flipped data byte in a stored entry: its CRC-32 no longer matches.
  std::string flipped = good;
  flipped[flipped.find("stored")] = 'S';
  EXPECT_NE(error_of(flipped).find("b.txt: CRC-32 mismatch"), std::string::npos) << error_of(flipped);
  // Deflated data cut short.
  std::string cut = good;
  const std::size_t at = cut.find("model.osim") + 10;
  cut[at] = static_cast<char>(cut[at] ^ 0x5a);
  EXPECT_NE(error_of(cut).find("model.osim"), std::string::npos) << error_of(cut);
  // An archive that unpacks to more than allowed (a zip bomb) stops before inflating.
  cpgait::services::ZipReadOptions small;
  small.max_total_bytes = 4000;
  EXPECT_NE(error_of(good, small).find("unpacks to more than 4000 bytes"), std::string::npos) << error_of(good, small);
  // Truncated anywhere: an error, never a crash.
  for (std::size_t n = 0; n < good.size(); n += 7) {
    try {
      read_zip(good.substr(0, n), "model.zip");
    } catch (const InputError&) {
    }
  }
}
