// Issue 21, acceptance 3: a C3D with force plates runs the pipeline by itself. gait2392 subject01's
// walk (TRC) and ground reactions (GRF .mot, the right and left feet's) exported as a Z-up lab's C3D
// with two plates; `cpgait run` on the C3D alone against `cpgait run` on what `cpgait convert` writes
// from it (TRC, GRF .mot, loads .xml), and against the original TRC and GRF.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "c3d_writer.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "test_support.h"

using namespace cpgait;

namespace {

// Per column, the largest difference (IK) or the RMS over time (ID, SO activations).
double largest_column_difference(const Storage& a, const Storage& b, bool rms) {
  EXPECT_EQ(a.labels, b.labels);
  EXPECT_EQ(a.num_rows(), b.num_rows());
  double worst = 0;
  for (int c = 1; c < a.num_columns() && a.num_rows() == b.num_rows() && a.labels == b.labels; ++c) {
    const Eigen::VectorXd d = a.data.col(c) - b.data.col(c);
    worst = std::max(worst, rms ? std::sqrt(d.squaredNorm() / static_cast<double>(d.size())) : d.cwiseAbs().maxCoeff());
  }
  return worst;
}

}  // namespace

TEST(C3dPipeline, AC3dWithForcePlatesRunsAsTheFilesConvertWrites) {
  const std::string pl = refdata::gait2392("pipeline/"), generic = refdata::gait2392("model/gait2392_simbody.osim");
  for (const auto& f : {pl + "subject01_walk1.trc", pl + "subject01_walk1_grf.mot", pl + "subject01_walk1_grf.xml",
                        pl + "subject01_Setup_IK.xml", pl + "OutputReference/subject01_simbody.osim", generic})
    REQUIRE_REFERENCE(f);
  const std::string dir = refdata::temp_dir("c3d_pipeline");
  const MarkerTrial trc = read_trc(pl + "subject01_walk1.trc");
  const Storage grf = read_storage(pl + "subject01_walk1_grf.mot");
  const std::vector<std::string> labels(grf.labels.begin(), grf.labels.end());
  {
    std::ofstream out(dir + "/walk.c3d", std::ios::binary);
    out << cpgait::testing::format_c3d_z_up_with_plates(trc, grf.data, labels, {"ground_force_", "1_ground_force_"}, 10);
  }
  std::ofstream(dir + "/options.json") << R"({"stages": ["ik", "id", "so"]})";
  const std::string common = "run --model " + pl + "OutputReference/subject01_simbody.osim --scale-muscles-from " + generic +
                             " --ik-tasks " + pl + "subject01_Setup_IK.xml --options " + dir + "/options.json --name walk";
  const auto a = refdata::run_cpgait(common + " --markers " + dir + "/walk.c3d -o " + dir + "/a");
  ASSERT_EQ(a.status, 0) << a.output;
  const auto conv = refdata::run_cpgait("convert " + dir + "/walk.c3d -o " + dir + "/conv");
  ASSERT_EQ(conv.status, 0) << conv.output;
  EXPECT_NE(conv.output.find("plate 1: right foot"), std::string::npos) << conv.output;
  EXPECT_NE(conv.output.find("plate 2: left foot"), std::string::npos) << conv.output;
  const auto b = refdata::run_cpgait(common + " --markers " + dir + "/conv/walk.trc --grf " + dir + "/conv/walk_grf.mot --loads " + dir +
                                     "/conv/walk_grf.xml -o " + dir + "/b");
  ASSERT_EQ(b.status, 0) << b.output;
  const auto c = refdata::run_cpgait(common + " --markers " + pl + "subject01_walk1.trc --grf " + pl + "subject01_walk1_grf.mot --loads " +
                                     pl + "subject01_walk1_grf.xml -o " + dir + "/c");
  ASSERT_EQ(c.status, 0) << c.output;
  // The loads the run derived are the ones convert writes.
  EXPECT_EQ(text::read_file(dir + "/a/walk_grf.mot"), text::read_file(dir + "/conv/walk_grf.mot"));
  EXPECT_EQ(text::read_file(dir + "/a/walk_grf.xml"), text::read_file(dir + "/conv/walk_grf.xml"));
  auto table = [&](const std::string& run, const std::string& suffix) { return read_storage(dir + "/" + run + "/walk" + suffix); };
  const double ik = largest_column_difference(table("a", "_ik.mot"), table("b", "_ik.mot"), false);
  const double id = largest_column_difference(table("a", "_id.sto"), table("b", "_id.sto"), true);
  const double so = largest_column_difference(table("a", "_StaticOptimization_activation.sto"), table("b", "_StaticOptimization_activation.sto"), true);
  const double id_original = largest_column_difference(table("a", "_id.sto"), table("c", "_id.sto"), true);
  std::printf("C3D alone vs converted files: IK %.1e deg, ID %.1e N m RMS, SO %.1e RMS; ID vs the original TRC + GRF %.3f N m RMS\n", ik,
              id, so, id_original);
  // The converted TRC holds mm to 6 decimals and the GRF 12 digits: the runs agree to that.
  EXPECT_LT(ik, 1e-4);
  EXPECT_LT(id, 1e-3);
  EXPECT_LT(so, 1e-4);
  if (!::testing::Test::HasFailure()) std::filesystem::remove_all(dir);
  else std::printf("kept %s\n", dir.c_str());
}
