#pragma once
// One entry per reader of outside input, shared by the libFuzzer targets (scripts/fuzz.sh builds them
// with clang's sanitizers) and by the suite's replay of the regression inputs (tests/fuzz/regressions).
// A reader may return or throw InputError; anything else escapes, and is a finding.
#include <string>
#include <string_view>
#include <vector>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/scale_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/model/osim_reader.h"

namespace cpgait::testing {

inline const std::vector<std::string>& fuzz_target_names() {
  static const std::vector<std::string> names = {"trc", "storage", "c3d", "osim", "external_loads", "ik_tasks_json", "scale_setup"};
  return names;
}

inline void fuzz_one(std::string_view target, std::string_view bytes) {
  try {
    if (target == "trc") {
      parse_trc(bytes, "fuzz.trc");
    } else if (target == "storage") {
      parse_storage(bytes, "fuzz.sto");
    } else if (target == "c3d") {
      const C3dFile f = parse_c3d(bytes, "fuzz.c3d");
      ground_reactions(f, c3d_to_opensim(f, C3dVertical::kAuto));
    } else if (target == "osim") {
      parse_osim(std::string(bytes), "fuzz.osim");
    } else if (target == "external_loads") {
      parse_external_loads(std::string(bytes), "fuzz.xml");
    } else if (target == "ik_tasks_json") {
      parse_ik_tasks_json(std::string(bytes), "fuzz.json");
    } else if (target == "scale_setup") {
      parse_scale_setup(std::string(bytes), "fuzz.xml");
    }
  } catch (const InputError&) {
  }
}

}  // namespace cpgait::testing
