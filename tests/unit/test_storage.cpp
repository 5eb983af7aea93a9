#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "test_support.h"

using namespace cpgait;

namespace {
const char* kSto =
    "Coordinates\nversion=1\nnRows=3\nnColumns=3\ninDegrees=yes\n\nUnits are S.I. units\nendheader\n"
    "time\tknee_angle_r\tpelvis_tx\n"
    "0.0\t-10.5\t0.5\n0.01\t-11\t0.51\n0.02\t-12.25\t0.52\n";

InputError expect_error(const std::string& content) {
  try {
    parse_storage(content, "bad.sto");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "expected an InputError";
  return InputError("", 0, "", "");
}
}  // namespace

TEST(Storage, ReadsCurrentHeader) {
  const Storage s = parse_storage(kSto, "a.sto");
  EXPECT_EQ(s.name, "Coordinates");
  ASSERT_TRUE(s.in_degrees.has_value());
  EXPECT_TRUE(*s.in_degrees);
  EXPECT_EQ(s.num_rows(), 3);
  EXPECT_EQ(s.column("pelvis_tx"), 2);
  EXPECT_EQ(s.column("nope"), -1);
  EXPECT_DOUBLE_EQ(s.data(2, 1), -12.25);
}

TEST(Storage, RoundTripKeepsValuesLabelsAndFlags) {
  Storage s = parse_storage(kSto, "a.sto");
  s.data(1, 2) = 1.0 / 3.0;
  const Storage back = parse_storage(format_storage(s, 17), "back.sto");
  EXPECT_EQ(back.labels, s.labels);
  EXPECT_EQ(back.in_degrees, s.in_degrees);
  EXPECT_EQ(back.name, s.name);
  EXPECT_EQ(back.extra_header, s.extra_header);
  EXPECT_EQ((back.data - s.data).cwiseAbs().maxCoeff(), 0.0);
}

// The tables' writer formats as printf's %.*g (the files OpenSim and earlier cpgait runs wrote):
// every value in every range, byte for byte, at the precisions it is used with and at the ends.
TEST(Storage, FormatGeneralWritesWhatPrintfWrites) {
  std::mt19937_64 rng(7);
  std::vector<double> values = {0.0, -0.0, 1.0, -1.0, 0.5, 2.5, 0.125, 1e-15, 1e15, 9.99999999999951, 99999999999.95, 0.000123456789012,
                                0.0001, 0.00001, 123456789012.0, 1234567890123.0, 5e-324, 1.7976931348623157e308,
                                std::nan(""), -std::nan(""), INFINITY, -INFINITY};
  std::uniform_real_distribution<double> unit(1.0, 10.0);
  std::uniform_int_distribution<int> decade(-18, 18), sign(0, 1), digits_kept(1, 17);
  for (int i = 0; i < 40000; ++i) {  // every decade, printed values read back (few digits), and raw bit patterns
    const double v = unit(rng) * std::pow(10.0, decade(rng)) * (sign(rng) ? -1 : 1);
    values.push_back(v);
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.*g", digits_kept(rng), v);
    values.push_back(std::strtod(buf, nullptr));
    std::uint64_t bits = rng();
    double raw;
    std::memcpy(&raw, &bits, sizeof raw);
    values.push_back(raw);
  }
  for (int k = 0; k < 2000; ++k) values.push_back((k - 1000) / 8.0), values.push_back(k * 0.005);  // binary ties, round decimals
  int mismatches = 0;
  for (int digits : {1, 6, 10, 12, 15, 17})
    for (double v : values) {
      char fast[40], expected[40];
      const std::string got(fast, text::format_general(v, digits, fast));
      std::snprintf(expected, sizeof expected, "%.*g", digits, v);
      char via[40];
      const std::string chars(via, std::to_chars(via, via + sizeof via, v, std::chars_format::general, digits).ptr);
      if (got != chars && ++mismatches <= 10) ADD_FAILURE() << v << " at " << digits << " digits: " << got << " != " << chars;
      if (!std::isnan(v) && got != expected && ++mismatches <= 10)
        ADD_FAILURE() << v << " at " << digits << " digits: " << got << " != printf's " << expected;
    }
  EXPECT_EQ(mismatches, 0);
}

TEST(Storage, ReadsOldSimmHeader) {
  const std::string simm =
      "first trial\nnRows=2\nnColumns=2\n\n# SIMM Motion File Header:\nname first trial\ndatacolumns 2\n"
      "datarows 2\notherdata 1\nrange 0.5 0.6\nendheader\ntime\thip_flexion_r\n"
      "      0.50000000000000000000\t      19.25\n      0.6\t      18.76\n";
  const Storage s = parse_storage(simm, "old.mot");
  EXPECT_FALSE(s.in_degrees.has_value());
  EXPECT_EQ(s.num_rows(), 2);
  EXPECT_DOUBLE_EQ(s.data(1, 1), 18.76);
}

TEST(Storage, ErrorsNameLineAndColumn) {
  std::string bad = kSto;
  bad.replace(bad.find("-11"), 3, "x11");
  InputError e = expect_error(bad);
  EXPECT_EQ(e.line(), 11);
  EXPECT_EQ(e.field(), "knee_angle_r");

  e = expect_error(std::string(kSto).substr(0, std::string(kSto).size() - 6));  // last row cut
  EXPECT_EQ(e.line(), 12);
  EXPECT_EQ(e.field(), "pelvis_tx");

  // Fewer (or more) rows than nRows: OpenSim reads the rows; so does cpgait, and says so.
  std::string fewer = kSto;
  fewer.replace(fewer.find("nRows=3"), 7, "nRows=5");
  const Storage f = parse_storage(fewer, "fewer.sto");
  EXPECT_EQ(f.num_rows(), 3);
  ASSERT_EQ(f.warnings.size(), 1u);
  EXPECT_NE(f.warnings[0].find("nRows=5"), std::string::npos) << f.warnings[0];
  EXPECT_TRUE(parse_storage(kSto, "exact.sto").warnings.empty());

  std::string cols = kSto;
  cols.replace(cols.find("nColumns=3"), 10, "nColumns=4");
  EXPECT_EQ(expect_error(cols).field(), "nColumns");

  EXPECT_EQ(expect_error("no header\n1 2 3\n").field(), "endheader");
  std::string deg = kSto;
  deg.replace(deg.find("inDegrees=yes"), 13, "inDegrees=maybe");
  EXPECT_EQ(expect_error(deg).field(), "inDegrees");
}

TEST(StorageReference, ReadsOpenSimsSimmHeaderIkFile) {
  const std::string path = refdata::gait2392("pipeline/OutputReference/subject01_walk1_ik.mot");
  REQUIRE_REFERENCE(path);
  const Storage s = read_storage(path);
  EXPECT_EQ(s.num_rows(), 211);
  EXPECT_EQ(s.num_columns(), 165);
  EXPECT_EQ(s.labels[1], "pelvis_tx");
  EXPECT_DOUBLE_EQ(s.time()[0], 0.5);
  EXPECT_NEAR(s.time()[s.num_rows() - 1], 4.0, 1e-9);
}

TEST(StorageReference, RoundTripsOpenSimsIdOutput) {
  const std::string path = refdata::gait2392("pipeline/OutputReference/ResultsInverseDynamics/InverseDynamicsOutput.sto");
  REQUIRE_REFERENCE(path);
  const Storage s = read_storage(path);
  const Storage back = parse_storage(format_storage(s, 17), "back.sto");
  EXPECT_EQ(back.labels, s.labels);
  EXPECT_EQ((back.data - s.data).cwiseAbs().maxCoeff(), 0.0);
}

// OpenSim writes a simulation's final state twice (same time, same values): read once, as OpenSim
// reads it. A repeated time with other values is still an error.
TEST(StorageReference, ReadsOpenSimsRepeatedFinalRow) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/CMC/gait10dof18musc_subject_adjusted_Kinematics_q.sto");
  REQUIRE_REFERENCE(path);
  const Storage s = read_storage(path);
  const int n = s.num_rows();
  ASSERT_GT(n, 2);
  EXPECT_NEAR(s.time()[n - 1], 2.499, 1e-12);
  EXPECT_GT(s.time()[n - 1], s.time()[n - 2]);

  std::string twice = kSto;
  const std::size_t last = twice.rfind('\n', twice.size() - 2) + 1;
  const std::string last_row = twice.substr(last);
  const Storage once = parse_storage(twice + last_row, "twice.sto");
  EXPECT_EQ(once.num_rows(), parse_storage(kSto, "once.sto").num_rows());
  std::string other = last_row;
  other.replace(other.rfind('\t') + 1, std::string::npos, "42\n");
  EXPECT_EQ(expect_error(twice + other).field(), "time");
}
