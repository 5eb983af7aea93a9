#pragma once
// A trial's report: one self-contained HTML page (inline CSS, plots as SVG images in data: URLs, no
// scripts, nothing fetched) to attach to a clinical note or a paper.
#include <nlohmann/json.hpp>
#include <string>

#include "store.h"

namespace cpgait::services {

// trial: the stored record (summary, stages, options); model: its model's record (warnings), or
// null; cycles: trial_cycles_json's answer, or null when the trial has no gait cycles.
std::string trial_report_html(const TrialRecord& trial, const ModelRecord* model, const nlohmann::json& cycles);

// One gait-cycle plot as an SVG document: each series' strides thin, its mean bold over a mean ± SD
// band, x 0-100 % of the cycle. series: entries of a cycles panel (name, side, unit, strides, mean, sd).
std::string cycle_plot_svg(const std::string& title, const nlohmann::json& series, const nlohmann::json& percent);

}  // namespace cpgait::services
