#pragma once
// What the API tests do with a server: synthetic trials of the built-in walker, upload forms, JSON
// bodies, waiting for a trial to end.
#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/model/osim_reader.h"
#include "test_support.h"

// Last: httplib pulls in <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace cpgait::apitest {
using nlohmann::json;

inline std::string slurp(const std::string& path) { return cpgait::text::read_file(path); }

inline std::string synthetic_trc(double duration_s, std::uint32_t seed = 1) {
  const cpgait::Model m = cpgait::read_osim(cpgait::refdata::fixture("models/walker.osim")).model;
  cpgait::fixtures::SyntheticTrialOptions o;
  o.duration_s = duration_s;
  o.noise_m = 0.0005;
  o.seed = seed;
  return cpgait::format_trc(cpgait::fixtures::synthesize_trial(m, o).markers, "mm");
}

inline httplib::MultipartFormDataItems trial_form(const std::string& trc, const std::string& trc_name, const json& options) {
  return {{"markers", trc, trc_name, "text/plain"}, {"options", options.dump(), "options.json", "application/json"}};
}

inline json body(const httplib::Result& r) { return json::parse(r->body); }

inline std::string wait_finished(httplib::Client& c, const std::string& id, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    auto r = c.Get(("/api/v1/trials/" + id).c_str());
    if (r && r->status == 200) {
      const std::string s = body(r)["status"];
      if (s == "done" || s == "failed" || s == "cancelled") return s;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return "timeout";
}

}  // namespace cpgait::apitest
