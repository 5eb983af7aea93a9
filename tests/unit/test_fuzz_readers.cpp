// Randomized corruption of real files: every reader either returns or throws InputError — never
// crashes, hangs, or throws anything else. Real OpenSim files from ../shared are used when present,
// cpgait's own fixture model and a synthetic trial always.
#include <gtest/gtest.h>

#include <cstdio>

#include <fstream>
#include <random>
#include <sstream>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

using namespace cpgait;

namespace {

std::string slurp(const std::string& path) { return text::read_file(path); }

// One random corruption: truncation, byte changes, a dropped or duplicated line, a huge number.
std::string mutate(const std::string& s, std::mt19937& rng) {
  std::uniform_int_distribution<std::size_t> pos(0, s.empty() ? 0 : s.size() - 1);
  std::string out = s;
  switch (std::uniform_int_distribution<int>(0, 6)(rng)) {
    case 0:
      return out.substr(0, pos(rng));
    case 1:
      for (int k = 0; k < 8 && !out.empty(); ++k) out[pos(rng)] = static_cast<char>(std::uniform_int_distribution<int>(1, 255)(rng));
      return out;
    case 2: {
      const std::size_t a = out.find('\n', pos(rng));
      const std::size_t b = a == std::string::npos ? a : out.find('\n', a + 1);
      if (b != std::string::npos) out.erase(a, b - a);
      return out;
    }
    case 3: {
      const std::size_t a = out.find('\n', pos(rng));
      const std::size_t b = a == std::string::npos ? a : out.find('\n', a + 1);
      if (b != std::string::npos) out.insert(a, out.substr(a, b - a));
      return out;
    }
    case 4: {
      const std::size_t a = out.find_first_of("0123456789", pos(rng));
      if (a != std::string::npos) out.insert(a, "99999999999");
      return out;
    }
    case 5: {
      static const char* kTokens[] = {"\t", " ", "nan", "-", "<", ">", "</", "\"", "e308", "\r"};
      out.insert(pos(rng), kTokens[std::uniform_int_distribution<int>(0, 9)(rng)]);
      return out;
    }
    default:
      out.insert(pos(rng), std::string(std::uniform_int_distribution<int>(1, 40)(rng), '\t'));
      return out;
  }
}

template <typename Parse>
void fuzz(const std::string& original, Parse parse, int rounds, std::uint32_t seed) {
  std::mt19937 rng(seed);
  int rejected = 0;
  for (int i = 0; i < rounds; ++i) {
    const std::string bad = mutate(original, rng);
    try {
      parse(bad);
    } catch (const InputError& e) {
      ++rejected;
      EXPECT_FALSE(std::string(e.what()).empty());
    } catch (const std::exception& e) {
      ADD_FAILURE() << "round " << i << ": unexpected exception type: " << e.what();
    }
  }
  // Most corruptions must be noticed; a reader that accepts everything is not checking.
  EXPECT_GT(rejected, rounds / 4) << "suspiciously few corruptions were rejected";
}

std::string synthetic_trc() {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  fixtures::SyntheticTrialOptions o;
  o.duration_s = 0.2;
  o.gap_fraction = 0.3;
  return format_trc(fixtures::synthesize_trial(m, o).markers, "mm");
}

}  // namespace

TEST(Fuzz, TrcReaderSurvivesCorruption) {
  const std::string trc = synthetic_trc();
  fuzz(trc, [](const std::string& s) { parse_trc(s, "fuzz.trc"); }, 400, 1);
  const std::string real = refdata::gait2392("pipeline/subject01_walk1.trc");
  if (std::filesystem::exists(real)) {
    fuzz(slurp(real), [](const std::string& s) { parse_trc(s, "fuzz.trc"); }, 150, 2);
  } else {
    std::printf("[ info ] not run: fuzzing OpenSim's walking TRC (%s absent)\n", real.c_str());
  }
}

TEST(Fuzz, StorageReaderSurvivesCorruption) {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  Storage s;
  s.name = "fuzz";
  s.in_degrees = true;
  s.labels = {"time", "a", "b"};
  s.data = Eigen::MatrixXd::Random(40, 3);
  for (int r = 0; r < 40; ++r) s.data(r, 0) = r * 0.01;
  fuzz(format_storage(s), [](const std::string& t) { parse_storage(t, "fuzz.sto"); }, 400, 3);
  const std::string real = refdata::gait2392("pipeline/OutputReference/subject01_walk1_ik.mot");
  if (std::filesystem::exists(real)) {
    fuzz(slurp(real), [](const std::string& t) { parse_storage(t, "fuzz.mot"); }, 60, 4);
  } else {
    std::printf("[ info ] not run: fuzzing OpenSim's IK .mot (%s absent)\n", real.c_str());
  }
}

TEST(Fuzz, OsimReaderSurvivesCorruption) {
  const std::string model = slurp(refdata::fixture("models/walker.osim"));
  fuzz(model, [](const std::string& s) { parse_osim(s, "fuzz.osim"); }, 300, 5);
}

TEST(Fuzz, TaskJsonSurvivesCorruption) {
  const std::string json = R"({"markers": {"R.ASIS": 10, "Top.Head": {"weight": 0.1, "apply": true}},
    "coordinates": {"subtalar_angle_r": {"weight": 1000, "value_type": "manual_value", "value": 0.1}}})";
  fuzz(json, [](const std::string& s) { parse_ik_tasks_json(s, "fuzz.json"); }, 300, 6);
}

TEST(Fuzz, LyingHeaderDoesNotAllocateUnboundedMemory) {
  // NumFrames and nRows claim billions of rows; the readers must fail on the real content.
  std::string trc = synthetic_trc();
  const std::size_t p = trc.find('\n', trc.find('\n') + 1) + 1;  // values line
  std::string line = trc.substr(p, trc.find('\n', p) - p);
  std::string huge = line;
  huge.replace(huge.find('\t', huge.find('\t') + 1) + 1, 2, "4000000000");
  trc.replace(p, line.size(), huge);
  EXPECT_THROW(parse_trc(trc, "lying.trc"), InputError);
  // A storage's nRows is a hint (OpenSim reads the rows present): the one real row, and a warning,
  // without reserving for the claimed nine trillion.
  const Storage lying = parse_storage("x\nnRows=9000000000000\nnColumns=2\nendheader\ntime\ta\n0 1\n", "lying.sto");
  EXPECT_EQ(lying.num_rows(), 1);
  EXPECT_EQ(lying.warnings.size(), 1u);
}
