#pragma once
// One entry per reader of outside input, shared by the libFuzzer targets (scripts/fuzz.sh builds them
// with clang's sanitizers), by their seed corpus and by the suite's replay of the regression inputs
// (tests/fuzz/regressions). A reader may return or throw InputError; anything else escapes, and is a
// finding. The service's upload target also aborts on a 5xx or a response body that is not JSON.
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace cpgait::testing {

// The targets, in the order scripts/fuzz.sh runs them; tests/CMakeLists.txt lists the same names.
const std::vector<std::string>& fuzz_target_names();

void fuzz_one(std::string_view target, std::string_view bytes);

// Inputs made by code for each target (valid ones from the fixtures, and a few edge cases): the
// replay test runs them, scripts/fuzz.sh seeds the corpus with them.
std::map<std::string, std::vector<std::string>> fuzz_made_inputs();

}  // namespace cpgait::testing
