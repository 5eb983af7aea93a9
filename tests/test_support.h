#pragma once
// Where tests find OpenSim's reference data (../shared) and cpgait's fixtures. Tests that need the
// reference data skip with a message naming the missing path.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <sys/wait.h>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/model/model.h"
#include "cpgait/model/osim_reader.h"

namespace cpgait::refdata {

// ../shared, or CPGAIT_SHARED_DIR from the environment (set it to an empty folder to check that every
// reference test skips cleanly without the data).
inline std::string shared_dir() {
  const char* env = std::getenv("CPGAIT_SHARED_DIR");
  return env && *env ? env : CPGAIT_SHARED_DIR;
}
inline std::string shared_path(const std::string& relative) {
  return (std::filesystem::path(shared_dir()) / "reference" / relative).lexically_normal().string();
}
inline std::string gait2392(const std::string& relative) { return shared_path("opensim/gait2392/" + relative); }
inline std::string fixture(const std::string& relative) {
  return std::string(CPGAIT_FIXTURES_DIR) + "/" + relative;
}

// cpgait's own model (fixtures/models/walker.osim), read once.
inline const Model& walker() {
  static const Model m = read_osim(fixture("models/walker.osim")).model;
  return m;
}

// A pennate muscle's geometry and strength for the muscle models' unit tests; the caller adds its
// model's curves or parameters.
inline Muscle pennate_muscle(double max_isometric_force_N, double optimal_fiber_length_m, double tendon_slack_length_m,
                             double pennation_at_optimal_rad) {
  Muscle m;
  m.max_isometric_force_N = max_isometric_force_N;
  m.optimal_fiber_length_m = optimal_fiber_length_m;
  m.tendon_slack_length_m = tendon_slack_length_m;
  m.pennation_angle_at_optimal_rad = pennation_at_optimal_rad;
  m.sin_pennation_at_optimal = std::sin(pennation_at_optimal_rad);
  return m;
}

// The temp folders this process made: removed when it exits with every test passed, kept (and
// named) otherwise so that a failure's files can be read. Without it every run left its folders.
struct TempDirs {
  std::vector<std::filesystem::path> made;
  ~TempDirs() {
    const ::testing::UnitTest* u = ::testing::UnitTest::GetInstance();
    if (u->Passed()) {
      std::error_code ec;
      for (const auto& d : made) std::filesystem::remove_all(d, ec);
    } else {
      for (const auto& d : made) std::fprintf(stderr, "[ info ] kept %s\n", d.string().c_str());
    }
  }
};

// A fresh, empty folder under the system temp directory, unique to this process.
inline std::string temp_dir(const std::string& name) {
  static TempDirs dirs;
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / ("cpgait_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  if (std::find(dirs.made.begin(), dirs.made.end(), d) == dirs.made.end()) dirs.made.push_back(d);
  return d.string();
}

// A pose with every coordinate drawn uniformly within its range (clipped to +-2 or +-3).
inline Eigen::VectorXd random_pose(const Model& m, std::mt19937& rng, double limit = 3.0) {
  Eigen::VectorXd q(m.num_coordinates());
  for (int c = 0; c < m.num_coordinates(); ++c) {
    const auto& co = m.coordinates[c];
    q[c] = std::uniform_real_distribution<double>(std::max(co.range_min, -limit), std::min(co.range_max, limit))(rng);
  }
  return q;
}

// A measured figure held to two upper bounds: the target an issue or the GUIDE sets (kept), and a
// regression bound a few times the figure measured when the bound was set, so that a regression shows
// long before the target is reached. The test names both figures where it calls this.
inline ::testing::AssertionResult within_target_and_regression(double value, double target, double regression_bound) {
  if (value <= target && value <= regression_bound) return ::testing::AssertionSuccess();
  ::testing::AssertionResult f = ::testing::AssertionFailure() << value;
  if (value > target) f << " exceeds the target " << target;
  if (value > regression_bound) f << (value > target ? " and" : "") << " exceeds the regression bound " << regression_bound;
  return f;
}

// The column of `label`. Absent, it throws (gtest reports the test failed), so no test reads column -1.
inline int required_column(const Storage& s, const std::string& label) {
  const int c = s.column(label);
  if (c < 0) throw std::runtime_error("no column '" + label + "' in " + (s.name.empty() ? std::string("the table") : s.name));
  return c;
}

// Pearson's correlation of two equally long series.
inline double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) ma += a[i] / n, mb += b[i] / n;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb + 1e-300);
}

// Per column both tables have (time aside): the RMS difference and the reference's peak |value| over
// the reference rows whose times ours has within time_tolerance_s, or, with interpolate, over those
// inside ours' time span, ours read linearly between its rows. Values as stored (degrees stay degrees).
struct ColumnDifference {
  double rms = 0, peak = 0;
  int rows = 0;
};
inline std::map<std::string, ColumnDifference> column_differences(const Storage& ours, const Storage& reference,
                                                                  double time_tolerance_s = 1e-6, bool interpolate = false) {
  std::map<std::string, ColumnDifference> out;
  const Eigen::VectorXd t = ours.time();
  for (int c = 1; c < reference.num_columns(); ++c) {
    const std::string& label = reference.labels[static_cast<std::size_t>(c)];
    const int o = ours.column(label);
    if (o < 1 || ours.num_rows() < 2) continue;
    ColumnDifference d;
    double sum2 = 0;
    for (int k = 0; k < reference.num_rows(); ++k) {
      const double tk = reference.time()[k];
      const Eigen::Index j = std::clamp<Eigen::Index>(std::upper_bound(t.data(), t.data() + t.size(), tk) - t.data(), 1, t.size() - 1);
      double value;
      if (std::abs(t[j - 1] - tk) <= time_tolerance_s || std::abs(t[j] - tk) <= time_tolerance_s) {
        value = ours.data(std::abs(t[j - 1] - tk) <= time_tolerance_s ? j - 1 : j, o);
      } else if (interpolate && tk > t[j - 1] && tk < t[j]) {
        const double w = (tk - t[j - 1]) / (t[j] - t[j - 1]);
        value = (1 - w) * ours.data(j - 1, o) + w * ours.data(j, o);
      } else {
        continue;
      }
      sum2 += std::pow(value - reference.data(k, c), 2);
      d.peak = std::max(d.peak, std::abs(reference.data(k, c)));
      ++d.rows;
    }
    d.rms = d.rows ? std::sqrt(sum2 / d.rows) : 0;
    out[label] = d;
  }
  return out;
}

// The gait stage's options for the walk held by pelvis residuals, untuned: the stage's defaults before
// 2026-11-29, for tests that check the other stages through a whole pipeline (the default tunes a
// controller to walk on its own, minutes on subject01).
inline constexpr const char* kResidualGaitOptions =
    R"({"residuals": true, "phase_reference": false, "foot_spheres": 2, "tune_evaluations": 0, "speed_knobs": []})";

#ifdef CPGAIT_BINARY
// The cpgait executable with these arguments: its exit status and everything it printed.
struct CliRun {
  int status;
  std::string output;
};
inline CliRun run_cpgait(const std::string& args) {
  CliRun r{0, ""};
  FILE* p = popen((std::string(CPGAIT_BINARY) + " " + args + " 2>&1").c_str(), "r");
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), p)) r.output += buf.data();
  const int s = pclose(p);
  r.status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  return r;
}
#endif

}  // namespace cpgait::refdata

// Skips the test when a reference file is absent.
#define REQUIRE_REFERENCE(path)                                                                   \
  do {                                                                                            \
    if (!std::filesystem::exists(path))                                                           \
      GTEST_SKIP() << "reference data absent: " << (path) << " (../shared/reference not present)"; \
  } while (0)
