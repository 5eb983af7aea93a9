#include "cpgait/gait/gain_margin.h"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <exception>
#include <stdexcept>
#include <thread>

namespace cpgait {

GainMarginSummary gain_margin(const Model& model, const CpgModel& cpg, const Storage& reference, const ContactSet& contacts,
                              const ReproducedGaitOptions& options, const GainMarginOptions& margin) {
  if (!(margin.factor > 0 && margin.factor < 1)) throw std::invalid_argument("gain_margin: the factor lies in (0, 1)");
  struct Gain {
    const char* name;
    double ReproducedGaitOptions::* field = nullptr;
    double SimbiconGains::* balance = nullptr;
    bool where_used = false;  // scaled only where the controller uses it (a zero scaled is the walk again)
  };
  const Gain gains[] = {{"reflex_kp", &ReproducedGaitOptions::reflex_kp},      {"reflex_kv", &ReproducedGaitOptions::reflex_kv},
                        {"trunk_kp", nullptr, &SimbiconGains::trunk_kp},       {"trunk_kv", nullptr, &SimbiconGains::trunk_kv},
                        {"lateral_d", nullptr, &SimbiconGains::lateral_d},     {"lateral_v", nullptr, &SimbiconGains::lateral_v},
                        {"sagittal_d", nullptr, &SimbiconGains::sagittal_d},   {"sagittal_v", nullptr, &SimbiconGains::sagittal_v},
                        {"swing_world", nullptr, &SimbiconGains::swing_world, true},
                        {"stance_lateral_d", nullptr, &SimbiconGains::stance_lateral_d, true},
                        {"stance_lateral_v", nullptr, &SimbiconGains::stance_lateral_v, true},
                        {"ankle_d", nullptr, &SimbiconGains::ankle_d, true},
                        {"ankle_v", nullptr, &SimbiconGains::ankle_v, true}};
  GainMarginSummary s;
  s.factor = margin.factor;
  std::vector<ReproducedGaitOptions> walks;
  for (const Gain& g : gains) {
    if (g.where_used && options.balance.*g.balance == 0) continue;
    for (double scale : {margin.factor, 1.0 / margin.factor}) {
      ReproducedGaitOptions o = options;
      if (g.field) o.*g.field *= scale;
      else o.balance.*g.balance *= scale;
      walks.push_back(o);
      s.walks.push_back({g.name, scale});
    }
  }
  std::atomic<std::size_t> next{0};
  std::exception_ptr failure;
  std::atomic<bool> failed{false};
  auto work = [&] {
    for (std::size_t i; (i = next++) < walks.size();) {
      try {
        const ReproducedGaitResult r = reproduce_gait(model, cpg, reference, contacts, walks[i]);
        s.walks[i].fell = r.fell_at_s >= 0;
        s.walks[i].walked_s = s.walks[i].fell ? r.fell_at_s : walks[i].duration_s;
      } catch (...) {
        if (!failed.exchange(true)) failure = std::current_exception();
      }
    }
  };
  const int hardware = static_cast<int>(std::thread::hardware_concurrency());
  const int threads = std::max(1, std::min(static_cast<int>(walks.size()), margin.num_threads > 0 ? margin.num_threads : hardware));
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  std::vector<double> walked;
  for (const GainMarginWalk& w : s.walks) s.still_walking += !w.fell, walked.push_back(w.walked_s);
  std::sort(walked.begin(), walked.end());
  const std::size_t n = walked.size();
  s.median_walked_s = n % 2 ? walked[n / 2] : 0.5 * (walked[n / 2 - 1] + walked[n / 2]);
  return s;
}

nlohmann::json GainMarginSummary::to_json() const {
  nlohmann::json list = nlohmann::json::array();
  for (const GainMarginWalk& w : walks) list.push_back({{"gain", w.gain}, {"scale", w.scale}, {"walked_s", w.walked_s}, {"fell", w.fell}});
  return {{"factor", factor}, {"still_walking", still_walking}, {"median_walked_s", median_walked_s}, {"walks", list}};
}

std::string GainMarginSummary::BriefReport() const {
  char buf[160];
  std::snprintf(buf, sizeof buf, "gain margin: %d of %zu walks with one gain scaled still walk; median %.2f s", still_walking, walks.size(),
                median_walked_s);
  std::string report = buf;
  for (const GainMarginWalk& w : walks) {
    std::snprintf(buf, sizeof buf, "\n  %-10s x %-5.3g %s %.2f s", w.gain.c_str(), w.scale, w.fell ? "fell at" : "walked", w.walked_s);
    report += buf;
  }
  return report;
}

}  // namespace cpgait
