#include <gtest/gtest.h>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/storage.h"
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
