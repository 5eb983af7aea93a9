// Writes each fuzz target's made inputs (tests/fuzz/fuzz_targets.h) into CORPUS/<target>/made-N.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "fuzz/fuzz_targets.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds CORPUS_DIR\n");
    return 2;
  }
  for (const auto& [target, inputs] : cpgait::testing::fuzz_made_inputs()) {
    const std::filesystem::path dir = std::filesystem::path(argv[1]) / target;
    std::filesystem::create_directories(dir);
    for (std::size_t i = 0; i < inputs.size(); ++i)
      std::ofstream(dir / ("made-" + std::to_string(i)), std::ios::binary) << inputs[i];
  }
  return 0;
}
