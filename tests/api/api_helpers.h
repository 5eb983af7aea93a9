#pragma once
// What the API tests do with a server: synthetic trials of the built-in walker, upload forms, JSON
// bodies, waiting for a trial to end.
#include <gtest/gtest.h>

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

// A request that got no answer (refused, timed out) fails the test with httplib's reason and gives an
// empty object, where dereferencing it crashed the test's process (seen once in CI on a loaded machine).
inline json body(const httplib::Result& r) {
  if (!r) {
    ADD_FAILURE() << "no answer from the server: " << httplib::to_string(r.error());
    return json::object();
  }
  return json::parse(r->body);
}

// The built-in walker, its gait held by residuals untuned: the long trials that keep workers busy run
// as before 2026-11-29 (the gait stage's default tunes a controller for minutes).
inline json walker_with_residual_gait() { return {{"model", "walker"}, {"gait", json::parse(cpgait::refdata::kResidualGaitOptions)}}; }

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

// Follows the trial's Server-Sent Events to the end; returns the final status and counts events.
inline std::string follow_events(httplib::Client& c, const std::string& id, int* progress_events = nullptr) {
  std::string buffer, status;
  int count = 0;
  c.set_read_timeout(120, 0);
  auto r = c.Get(("/api/v1/trials/" + id + "/events").c_str(), [&](const char* data, size_t n) {
    buffer.append(data, n);
    std::size_t p;
    while ((p = buffer.find("\n\n")) != std::string::npos) {
      const std::string msg = buffer.substr(0, p);
      buffer.erase(0, p + 2);
      if (msg.rfind("event: progress", 0) == 0) ++count;
      if (msg.rfind("event: end", 0) == 0) status = json::parse(msg.substr(msg.find("data: ") + 6))["status"];
    }
    return true;
  });
  EXPECT_TRUE(r) << "SSE request failed";
  if (progress_events) *progress_events = count;
  return status;
}

}  // namespace cpgait::apitest
