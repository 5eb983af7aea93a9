// libFuzzer's entry for one reader, chosen at build time (-DCPGAIT_FUZZ_TARGET="trc"); see scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  cpgait::testing::fuzz_one(CPGAIT_FUZZ_TARGET, std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}
