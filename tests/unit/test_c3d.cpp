// C3D: the vendors' files in ../shared as their parameters state them (with the values ezc3d's own
// tests assert for these files), and a synthetic round trip through every processor format.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <cstring>
#include <random>
#include <functional>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "c3d_writer.h"
#include "test_support.h"

using namespace cpgait;

namespace {

std::string c3d_path(const std::string& file) { return refdata::shared_path("c3d/" + file); }

// Sum of every valid coordinate in the file's units, as ezc3d's test sums them.
double coordinate_sum_in_file_units(const C3dFile& f) {
  double sum = 0;
  const double per_metre = 1.0 / metres_per_unit(f.markers.units_in_file);
  for (Eigen::Index k = 0; k < f.markers.positions_m.cols(); ++k)
    if (f.markers.positions_m.col(k).allFinite()) sum += f.markers.positions_m.col(k).sum() * per_metre;
  return sum;
}

}  // namespace

TEST(C3dReference, ReadsViconNexusAsItsParametersState) {
  const std::string path = c3d_path("Vicon.c3d");
  REQUIRE_REFERENCE(path);
  const C3dFile f = read_c3d(path);
  EXPECT_EQ(f.processor, C3dFile::Processor::kIntel);
  EXPECT_TRUE(f.floating_point);  // POINT:SCALE -0.01
  EXPECT_EQ(f.markers.num_markers(), 51);
  EXPECT_EQ(f.markers.num_frames(), 580);
  EXPECT_DOUBLE_EQ(f.markers.data_rate_hz, 100);
  EXPECT_EQ(f.first_frame, 1);
  EXPECT_EQ(f.markers.units_in_file, "mm");
  ASSERT_NE(f.parameter("POINT", "USED"), nullptr);
  EXPECT_EQ(f.parameter("POINT", "USED")->numbers.at(0), 51);
  EXPECT_EQ(f.parameter("MANUFACTURER", "COMPANY")->strings.at(0), "Vicon");
  EXPECT_EQ(f.parameter("MANUFACTURER", "SOFTWARE")->strings.at(0), "Vicon Nexus");
  // ezc3d's values for this file: frame 0 point 0 x, the last frame's point 50 z, the sum of all valid coordinates (mm).
  EXPECT_NEAR(f.markers.position_m(0, 0).x(), 44.16278839111328e-3, 1e-12);
  EXPECT_NEAR(f.markers.position_m(579, 50).z(), 99.682586669921875e-3, 1e-12);
  EXPECT_NEAR(coordinate_sum_in_file_units(f), 42506014.918278672, 1e-6 * 42506014.918278672);
  // Analog: 38 channels at 2000 Hz, 20 samples per frame.
  EXPECT_EQ(f.analog.labels.size(), 38u);
  EXPECT_DOUBLE_EQ(f.analog.rate_hz, 2000);
  EXPECT_EQ(f.analog.samples_per_frame, 20);
  EXPECT_EQ(f.analog.values.rows(), 580 * 20);
  EXPECT_EQ(f.analog.values.cols(), 38);
  EXPECT_TRUE(f.analog.values.allFinite());
  EXPECT_EQ(f.parameter("FORCE_PLATFORM", "USED")->numbers.at(0), 0);
  std::printf("[ info ] Vicon.c3d: %d markers x %d frames at %.0f Hz (%s), %zu analog channels at %.0f Hz, %zu marker gaps\n",
              f.markers.num_markers(), f.markers.num_frames(), f.markers.data_rate_hz, f.markers.units_in_file.c_str(), f.analog.labels.size(),
              f.analog.rate_hz, f.markers.gaps().size());
}

TEST(C3dReference, ReadsQualisysAndBtsAsTheirParametersState) {
  for (const auto& file : {"Qualisys.c3d", "BTS.c3d"}) REQUIRE_REFERENCE(c3d_path(file));
  const C3dFile q = read_c3d(c3d_path("Qualisys.c3d"));
  EXPECT_EQ(q.markers.num_markers(), 55);
  EXPECT_EQ(q.markers.num_frames(), 340);
  EXPECT_DOUBLE_EQ(q.markers.data_rate_hz, 200);
  EXPECT_EQ(q.first_frame, 705);  // ezc3d's 0-based 704
  EXPECT_EQ(q.markers.frame_numbers.front(), 705);
  EXPECT_NEAR(q.markers.time_s.front(), 704 / 200.0, 1e-12);
  EXPECT_EQ(q.analog.labels.size(), 69u);
  EXPECT_DOUBLE_EQ(q.analog.rate_hz, 2000);
  EXPECT_EQ(q.analog.samples_per_frame, 10);
  EXPECT_EQ(q.parameter("MANUFACTURER", "COMPANY")->strings.at(0), "Qualisys");
  EXPECT_EQ(q.parameter("FORCE_PLATFORM", "USED")->numbers.at(0), 2);
  EXPECT_EQ(q.parameter("FORCE_PLATFORM", "CORNERS")->numbers.size(), 24u);
  EXPECT_EQ(q.parameter("FORCE_PLATFORM", "CHANNEL")->numbers.size(), 12u);

  const C3dFile b = read_c3d(c3d_path("BTS.c3d"));
  EXPECT_EQ(b.markers.num_markers(), 22);
  EXPECT_EQ(b.markers.num_frames(), 675);
  EXPECT_DOUBLE_EQ(b.markers.data_rate_hz, 100);
  EXPECT_EQ(b.first_frame, 1);
  EXPECT_EQ(b.analog.labels.size(), 44u);
  EXPECT_DOUBLE_EQ(b.analog.rate_hz, 1000);
  EXPECT_EQ(b.analog.samples_per_frame, 10);
  EXPECT_EQ(b.parameter("FORCE_PLATFORM", "USED")->numbers.at(0), 6);
  EXPECT_EQ(b.parameter("FORCE_PLATFORM", "TYPE")->numbers.size(), 6u);
  EXPECT_EQ(b.parameter("FORCE_PLATFORM", "CORNERS")->numbers.size(), 72u);
  for (const C3dFile* f : {&q, &b}) {
    for (const auto& name : f->markers.marker_names) EXPECT_FALSE(name.empty()) << f->name;
    std::printf("[ info ] %s: %d markers x %d frames at %.0f Hz (%s, %s), %zu analog channels at %.0f Hz, %zu marker gaps\n", f->name.c_str(),
                f->markers.num_markers(), f->markers.num_frames(), f->markers.data_rate_hz, f->markers.units_in_file.c_str(),
                f->floating_point ? "float" : "integer", f->analog.labels.size(), f->analog.rate_hz, f->markers.gaps().size());
  }
}

namespace {
using cpgait::testing::C3dWriter;

// 3 markers x 5 frames, 2 analog channels x 2 samples a frame; marker 1 missing in frame 2.
std::string synthetic_c3d(int processor, bool floating) {
  const int points = 3, frames = 5, channels = 2, samples = 2;
  const float scale = floating ? -0.1f : 0.1f;
  C3dWriter w;
  w.processor = processor;
  // Header (block 1): parameters at block 2, data at block 4.
  w.u8(2), w.u8(0x50);
  w.i16(points), w.i16(channels * samples), w.i16(1), w.i16(frames), w.i16(0);
  w.f32(scale);
  w.i16(4), w.i16(samples);
  w.f32(50.0f);
  w.pad();
  // Parameters (blocks 2-3).
  w.u8(1), w.u8(0x50), w.u8(2), w.u8(processor);
  w.group(1, "POINT");
  w.parameter(1, "USED", 2, {}, [&] { w.i16(points); });
  w.parameter(1, "SCALE", 4, {}, [&] { w.f32(scale); });
  w.parameter(1, "RATE", 4, {}, [&] { w.f32(50.0f); });
  w.parameter(1, "UNITS", -1, {2}, [&] { w.out += "mm"; });
  w.parameter(1, "LABELS", -1, {4, points}, [&] { w.out += "RASI    LHEE"; });
  w.group(2, "ANALOG");
  w.parameter(2, "USED", 2, {}, [&] { w.i16(channels); });
  w.parameter(2, "LABELS", -1, {3, channels}, [&] { w.out += "FZ1FZ2"; });
  w.parameter(2, "SCALE", 4, {channels}, [&] { w.f32(0.5f), w.f32(2.0f); });
  w.parameter(2, "OFFSET", 2, {channels}, [&] { w.i16(10), w.i16(-4); });
  w.parameter(2, "GEN_SCALE", 4, {}, [&] { w.f32(1.5f); });
  w.parameter(2, "RATE", 4, {}, [&] { w.f32(100.0f); });
  w.u8(0), w.u8(0);  // end of the parameters
  w.pad();
  w.out.resize(3 * 512, '\0');
  // Data (block 4): raw values v(f, p, a) = 10 f + 3 p + a (scaled by 0.1 for integers, as stored for floats).
  for (int f = 0; f < frames; ++f) {
    for (int p = 0; p < points; ++p) {
      for (int a = 0; a < 3; ++a) {
        const int raw = 100 * f + 30 * p + 10 * a + 7;
        floating ? w.f32(static_cast<float>(raw)) : w.i16(raw);
      }
      const int residual = p == 1 && f == 2 ? -1 : 2;
      floating ? w.f32(static_cast<float>(residual)) : w.i16(residual);
    }
    for (int s = 0; s < samples; ++s)
      for (int c = 0; c < channels; ++c) floating ? w.f32(static_cast<float>(f * 20 + s * 5 + c)) : w.i16(f * 20 + s * 5 + c);
  }
  w.pad();
  return w.out;
}

}  // namespace

TEST(C3d, SyntheticRoundTripInEveryProcessorFormatAndDataType) {
  for (int processor : {84, 85, 86}) {
    for (bool floating : {false, true}) {
      SCOPED_TRACE("processor " + std::to_string(processor) + (floating ? " float" : " integer"));
      const C3dFile f = parse_c3d(synthetic_c3d(processor, floating), "synthetic.c3d");
      EXPECT_EQ(static_cast<int>(f.processor), processor - 84);
      EXPECT_EQ(f.floating_point, floating);
      ASSERT_EQ(f.markers.num_markers(), 3);
      ASSERT_EQ(f.markers.num_frames(), 5);
      EXPECT_EQ(f.markers.marker_names, (std::vector<std::string>{"RASI", "M2", "LHEE"}));  // a blank label gets a name
      EXPECT_DOUBLE_EQ(f.markers.data_rate_hz, 50);
      EXPECT_NEAR(f.markers.time_s[4], 4 / 50.0, 1e-15);
      const double unit = (floating ? 1.0 : static_cast<double>(0.1f)) * 1e-3;  // integers times POINT:SCALE (a float); mm to m
      for (int fr = 0; fr < 5; ++fr)
        for (int p = 0; p < 3; ++p)
          for (int a = 0; a < 3; ++a) {
            const double expected = (100 * fr + 30 * p + 10 * a + 7) * unit;
            if (p == 1 && fr == 2) {
              EXPECT_TRUE(std::isnan(f.markers.position_m(fr, p)[a]));
            } else {
              EXPECT_NEAR(f.markers.position_m(fr, p)[a], expected, 1e-12 * std::abs(expected)) << fr << " " << p << " " << a;
            }
          }
      ASSERT_EQ(f.markers.gaps().size(), 1u);
      EXPECT_EQ(f.analog.labels, (std::vector<std::string>{"FZ1", "FZ2"}));
      EXPECT_DOUBLE_EQ(f.analog.rate_hz, 100);
      ASSERT_EQ(f.analog.values.rows(), 10);
      for (int fr = 0; fr < 5; ++fr)
        for (int s = 0; s < 2; ++s) {
          const int raw0 = fr * 20 + s * 5, raw1 = raw0 + 1;
          EXPECT_NEAR(f.analog.values(fr * 2 + s, 0), (raw0 - 10) * 0.5 * 1.5, 1e-12);
          EXPECT_NEAR(f.analog.values(fr * 2 + s, 1), (raw1 + 4) * 2.0 * 1.5, 1e-12);
        }
    }
  }
}

// The DEC (VAX F) encoding the round trip relies on, checked against hand-encoded values: 50.0 is
// exponent 134 (bias 128) with fraction .11001 (hidden bit first), the word 0x4348 stored low byte first.
TEST(C3d, DecFloatsAreVaxF) {
  const std::string dec = synthetic_c3d(85, true);
  EXPECT_EQ(dec.substr(20, 4), std::string("\x48\x43\x00\x00", 4));  // the header's frame rate, 50.0
  // -2.5 (exponent 130, fraction .101, sign set: the word 0xC120) as the first point's x, in mm.
  std::string patched = dec;
  patched.replace(3 * 512, 4, std::string("\x20\xc1\x00\x00", 4));
  EXPECT_DOUBLE_EQ(parse_c3d(patched, "dec.c3d").markers.position_m(0, 0).x(), -2.5e-3);
}

TEST(C3d, DamagedFilesNameTheByteAndWhatWasExpected) {
  const std::string good = synthetic_c3d(84, true);
  auto refusal = [](const std::string& bytes) -> std::string {
    try {
      parse_c3d(bytes, "bad.c3d");
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "bad.c3d");
      return e.what();
    }
    ADD_FAILURE() << "accepted";
    return "";
  };
  // Truncated inside the data: the byte where the data would end.
  EXPECT_NE(refusal(good.substr(0, 3 * 512 + 100)).find("byte 1536: the file ends at byte 1636"), std::string::npos);
  // A frame count that lies.
  std::string lying = good;
  lying[8] = static_cast<char>(0xff), lying[9] = 0x7f;
  EXPECT_NE(refusal(lying).find("frames"), std::string::npos);
  // An unknown processor, a text file, an empty file.
  std::string processor = good;
  processor[512 + 3] = 99;
  EXPECT_NE(refusal(processor).find("processor type: byte 515: 99 (expected 84 Intel, 85 DEC or 86 MIPS)"), std::string::npos);
  EXPECT_NE(refusal("PathFileType\t4\t(X/Y/Z)\tx.trc\n").find("not a C3D file"), std::string::npos);
  EXPECT_NE(refusal("").find("not a C3D file"), std::string::npos);
  // A parameter pointing past the end of the file.
  std::string past = good.substr(0, 512 + 12);
  past.resize(512 + 12, '\0');
  past[512 + 4] = 4, past[512 + 5] = 1;  // a 4-character name running off the end
  EXPECT_NE(refusal(past).find("the file ends at byte"), std::string::npos);
  // Every truncation of a good file is refused cleanly or read as far as it goes, never a crash.
  for (std::size_t n = 0; n < good.size(); n += 37) {
    try {
      parse_c3d(good.substr(0, n), "cut.c3d");
    } catch (const InputError&) {
    }
  }
}

// Random damage to a synthetic file and to the first 64 KB of a vendor's (Qualisys: with force plates
// and events): only InputError from the reader and the plates' conversion, never a crash or another
// exception; every cut before the last block (where the data end) is refused.
TEST(C3d, RandomDamageGivesInputErrorsOnly) {
  std::vector<std::string> originals = {synthetic_c3d(84, false), synthetic_c3d(85, true), synthetic_c3d(86, true)};
  for (const char* vendor : {"Vicon.c3d", "Qualisys.c3d"}) {
    if (const std::string path = c3d_path(vendor); std::filesystem::exists(path)) {
      originals.push_back(text::read_file(path));
    } else {
      std::printf("[ info ] not run: damage to a vendor file (%s absent)\n", path.c_str());
    }
  }
  std::mt19937 rng(11);
  int rounds = 0, refused = 0;
  for (const std::string& original : originals) {
    const std::size_t span = std::min<std::size_t>(original.size(), 65536);
    for (int k = 0; k < 400; ++k, ++rounds) {
      std::string bad = original;
      const int kind = k % 3;
      if (kind == 0) {
        bad.resize(std::uniform_int_distribution<std::size_t>(0, original.size() - 1)(rng));
      } else {
        for (int n = 0; n < (kind == 1 ? 1 : 16); ++n)
          bad[std::uniform_int_distribution<std::size_t>(0, span - 1)(rng)] = static_cast<char>(std::uniform_int_distribution<int>(0, 255)(rng));
      }
      try {
        const C3dFile f = parse_c3d(bad, "damaged.c3d");
        ground_reactions(f, c3d_to_opensim(f, C3dVertical::kAuto));
        // The data end within the last 512-byte block (the rest is padding): a cut before it loses data.
        EXPECT_FALSE(kind == 0 && bad.size() + 512 <= original.size())
            << "a truncated file was accepted (" << bad.size() << " of " << original.size() << " bytes)";
      } catch (const InputError&) {
        ++refused;
      } catch (const std::exception& e) {
        ADD_FAILURE() << "round " << rounds << ": " << e.what();
      }
    }
  }
  std::printf("[ info ] %d damaged files: %d refused with InputError, the rest read (damaged values are not detectable)\n", rounds, refused);
}
