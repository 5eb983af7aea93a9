#include <gtest/gtest.h>

#include <cmath>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/trc.h"
#include "test_support.h"

using namespace cpgait;

namespace {

const char* kHeader =
    "PathFileType\t4\t(X/Y/Z)\ttest.trc\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n";

std::string two_marker_trc(const std::string& units, const std::string& rows, int frames = 3) {
  return std::string(kHeader) + "100\t100\t" + std::to_string(frames) + "\t2\t" + units + "\t100\t1\t" +
         std::to_string(frames) +
         "\n"
         "Frame#\tTime\tA\t\t\tB\t\t\n"
         "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
         "\n" +
         rows;
}

const char* kRows =
    "1\t0.00\t1\t2\t3\t4\t5\t6\n"
    "2\t0.01\t1.5\t2.5\t3.5\t4.5\t5.5\t6.5\n"
    "3\t0.02\t2\t3\t4\t5\t6\t7\n";

InputError expect_error(const std::string& content) {
  try {
    parse_trc(content, "bad.trc");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "expected an InputError";
  return InputError("", 0, "", "");
}

}  // namespace

TEST(Trc, ReadsHeaderAndConvertsMillimetresToMetres) {
  const MarkerTrial t = parse_trc(two_marker_trc("mm", kRows), "t.trc");
  EXPECT_EQ(t.num_frames(), 3);
  EXPECT_EQ(t.num_markers(), 2);
  EXPECT_EQ(t.marker_names[1], "B");
  EXPECT_DOUBLE_EQ(t.data_rate_hz, 100);
  EXPECT_EQ(t.units_in_file, "mm");
  EXPECT_DOUBLE_EQ(t.time_s[2], 0.02);
  EXPECT_NEAR(t.position_m(1, 1).x(), 4.5e-3, 1e-15);
  EXPECT_NEAR(t.position_m(2, 0).z(), 4e-3, 1e-15);
}

// Found by fuzzing (tests/fuzz/regressions/trc): a start frame past int's range was cast regardless.
TEST(Trc, ImplausibleOrigDataStartFrameIsRefused) {
  std::string content = two_marker_trc("mm", kRows);
  const std::size_t at = content.find("\t100\t1\t3\n");
  ASSERT_NE(at, std::string::npos);
  content.replace(at, 10, "\t100\t6422681820\t3\n");
  const InputError e = expect_error(content);
  EXPECT_EQ(e.field(), "OrigDataStartFrame");
  EXPECT_EQ(e.line(), 3);
}

TEST(Trc, UnitsCentimetresAndMetres) {
  EXPECT_NEAR(parse_trc(two_marker_trc("cm", kRows), "t").position_m(0, 1).y(), 0.05, 1e-15);
  EXPECT_NEAR(parse_trc(two_marker_trc("m", kRows), "t").position_m(0, 1).y(), 5.0, 1e-15);
  const InputError e = expect_error(two_marker_trc("inches", kRows));
  EXPECT_EQ(e.line(), 3);
  EXPECT_EQ(e.field(), "Units");
}

TEST(Trc, CrlfLineEndsTrailingTabsAndSpaces) {
  std::string crlf;
  for (char c : two_marker_trc("mm", "1\t0.00\t1\t2\t3\t4\t5\t6\t\t\n2\t0.01\t1\t2\t3\t4\t5\t6\t\n", 2)) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  const MarkerTrial t = parse_trc(crlf, "crlf.trc");
  EXPECT_EQ(t.num_frames(), 2);
  EXPECT_NEAR(t.position_m(1, 1).z(), 6e-3, 1e-15);

  std::string spaced = two_marker_trc("mm", kRows);
  for (char& c : spaced)
    if (c == '\t') c = ' ';
  const MarkerTrial s = parse_trc(spaced, "spaces.trc");
  EXPECT_EQ(s.num_markers(), 2);
  EXPECT_NEAR(s.position_m(2, 1).x(), 5e-3, 1e-15);
}

TEST(Trc, BlankCellsAreMissingMarkersWithAGapReport) {
  const MarkerTrial t = parse_trc(two_marker_trc("mm",
                                                  "1\t0.00\t1\t2\t3\t4\t5\t6\n"
                                                  "2\t0.01\t\t\t\t4\t5\t6\n"
                                                  "3\t0.02\t\t\t\t4\t5\t6\n"
                                                  "4\t0.03\t1\t2\t3\t\t\t\n",
                                                  4),
                                  "gaps.trc");
  EXPECT_TRUE(std::isnan(t.position_m(1, 0).x()));
  EXPECT_FALSE(std::isnan(t.position_m(0, 0).x()));
  const auto gaps = t.gaps();
  ASSERT_EQ(gaps.size(), 2u);
  EXPECT_EQ(gaps[0].marker, "A");
  EXPECT_EQ(gaps[0].first_frame, 1);
  EXPECT_EQ(gaps[0].last_frame, 2);
  EXPECT_DOUBLE_EQ(gaps[0].end_time_s, 0.02);
  EXPECT_EQ(gaps[1].marker, "B");
  EXPECT_EQ(gaps[1].first_frame, 3);
}

TEST(Trc, PartlyBlankMarkerIsMissingWithAWarning) {
  const MarkerTrial t =
      parse_trc(two_marker_trc("mm", "1\t0\t1\t\t3\t4\t5\t6\n2\t0.01\t1\t2\t3\t4\t5\t6\n", 2), "p.trc");
  EXPECT_TRUE(std::isnan(t.position_m(0, 0).x()));
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("p.trc:7"), std::string::npos);
}

TEST(Trc, ErrorsNameFileLineAndField) {
  InputError e = expect_error(two_marker_trc("mm", "1\t0.00\t1\t2\t3\t4\t5\t6\n2\t0.01\t1\tabc\t3\t4\t5\t6\n", 2));
  EXPECT_EQ(e.file(), "bad.trc");
  EXPECT_EQ(e.line(), 8);  // header 5 lines, a blank line, then data from line 7
  EXPECT_EQ(e.field(), "A.Y");
  EXPECT_NE(std::string(e.what()).find("abc"), std::string::npos);

  e = expect_error(two_marker_trc("mm", "1\t0.00\t1\t2\t3\t4\n"));  // row cut short
  EXPECT_EQ(e.line(), 7);
  EXPECT_EQ(e.field(), "B");


  e = expect_error(two_marker_trc("mm", "1\t0.00\t1\t2\t3\t4\t5\t6\n2\t0.00\t1\t2\t3\t4\t5\t6\n", 2));
  EXPECT_EQ(e.field(), "Time");

  e = expect_error(std::string(kHeader) + "100\t100\t3\t3\tmm\t100\t1\t3\n" + "Frame#\tTime\tA\t\t\tB\t\t\n\t\tX1\n\n" + kRows);
  EXPECT_EQ(e.field(), "NumMarkers");

  e = expect_error("");
  EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos);
  e = expect_error("hello\n");
  EXPECT_EQ(e.field(), "PathFileType");
  e = expect_error(std::string(kHeader));
  EXPECT_NE(std::string(e.what()).find("header"), std::string::npos);
}

// The quirks of files as labs and OpenSim's own tutorials have them; each is accepted as OpenSim
// accepts it.
TEST(Trc, HeaderValuesSeparatedByRunsOfTabs) {
  // The header lines of OpenSim's tutorial files (e.g. its gait tutorial's walking trial).
  const std::string trc =
      "PathFileType\t4\t(X/Y/Z)\twalk.trc\n"
      "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
      "100.0\t\t100.0\t\t3\t\t2\t\tmm\t\t100.0\t\t1\t\t3\n"
      "Frame#\tTime\tA\t\t\tB\t\t\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\n" +
      std::string(kRows);
  const MarkerTrial t = parse_trc(trc, "walk.trc");
  EXPECT_DOUBLE_EQ(t.data_rate_hz, 100.0);
  EXPECT_DOUBLE_EQ(t.camera_rate_hz, 100.0);
  EXPECT_EQ(t.num_frames(), 3);
  EXPECT_DOUBLE_EQ(t.position_m(2, 1).z(), 0.007);
}

TEST(Trc, RowsDecideTheFrameCountAndTheHeaderIsReported) {
  const MarkerTrial more = parse_trc(two_marker_trc("mm", kRows, 5), "short.trc");
  EXPECT_EQ(more.num_frames(), 3);
  ASSERT_EQ(more.warnings.size(), 1u);
  EXPECT_NE(more.warnings[0].find("NumFrames says 5 but 3 rows"), std::string::npos) << more.warnings[0];
  const MarkerTrial fewer = parse_trc(two_marker_trc("mm", kRows, 2), "long.trc");
  EXPECT_EQ(fewer.num_frames(), 3);
  EXPECT_EQ(fewer.warnings.size(), 1u);
}

TEST(Trc, NamesWithSpacesAndDotsBlankFrameNumbersAndTrailingCells) {
  const std::string trc = std::string(kHeader) + "100\t100\t2\t2\tmm\t100\t1\t2\n" +
                          "Frame#\tTime\tR.Heel Lat\t\t\tL.ASIS\t\t\t\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\n" +
                          "\t0.00\t1\t2\t3\t4\t5\t6\t99\n"
                          "\t0.01\t1\t2\t3\t4\t5\t6\t99\n";
  const MarkerTrial t = parse_trc(trc, "lab.trc");
  ASSERT_EQ(t.marker_names.size(), 2u);
  EXPECT_EQ(t.marker_names[0], "R.Heel Lat");
  EXPECT_EQ(t.marker_names[1], "L.ASIS");
  EXPECT_EQ(t.frame_numbers, (std::vector<int>{1, 2}));
  EXPECT_DOUBLE_EQ(t.position_m(1, 1).x(), 0.004);
  ASSERT_EQ(t.warnings.size(), 1u);  // the trailing cells, once
  EXPECT_NE(t.warnings[0].find("beyond the listed markers"), std::string::npos);
}

TEST(Trc, WriteThenReadRoundTrips) {
  MarkerTrial t = parse_trc(two_marker_trc("mm", kRows), "t.trc");
  t.position_m(1, 0).setConstant(std::nan(""));
  for (const char* units : {"mm", "cm", "m"}) {
    const MarkerTrial back = parse_trc(format_trc(t, units), "back.trc");
    ASSERT_EQ(back.num_frames(), t.num_frames());
    EXPECT_EQ(back.marker_names, t.marker_names);
    EXPECT_EQ(back.units_in_file, units);
    for (int f = 0; f < t.num_frames(); ++f) {
      EXPECT_DOUBLE_EQ(back.time_s[f], t.time_s[f]);
      for (int m = 0; m < t.num_markers(); ++m)
        for (int a = 0; a < 3; ++a) {
          if (std::isnan(t.position_m(f, m)[a])) EXPECT_TRUE(std::isnan(back.position_m(f, m)[a]));
          else EXPECT_NEAR(back.position_m(f, m)[a], t.position_m(f, m)[a], 1e-12);
        }
    }
  }
}

TEST(Trc, FileSizeLimit) {
  TrcReadOptions o;
  o.max_bytes = 100;
  EXPECT_THROW(parse_trc(two_marker_trc("mm", kRows), "big.trc", o), InputError);
}

TEST(TrcReference, ReadsOpenSimsWalkingTrial) {
  const std::string path = refdata::gait2392("pipeline/subject01_walk1.trc");
  REQUIRE_REFERENCE(path);
  const MarkerTrial t = read_trc(path);
  EXPECT_EQ(t.num_frames(), 151);
  EXPECT_EQ(t.num_markers(), 41);
  EXPECT_DOUBLE_EQ(t.data_rate_hz, 60);
  EXPECT_EQ(t.marker_names[0], "R.ASIS");
  EXPECT_NEAR(t.position_m(0, 0).x(), 0.61724762, 1e-12);  // 617.247620 mm
  EXPECT_NEAR(t.time_s.back(), 2.5, 1e-9);
  EXPECT_TRUE(t.gaps().empty());
}
