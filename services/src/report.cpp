#include "report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "output_files.h"
#include "review_data.h"

namespace cpgait::services {
using nlohmann::json;

namespace {

std::string escape_html(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string base64(const std::string& in) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const std::uint32_t n = static_cast<std::uint32_t>(static_cast<unsigned char>(in[i])) << 16 |
                            (i + 1 < in.size() ? static_cast<std::uint32_t>(static_cast<unsigned char>(in[i + 1])) << 8 : 0) |
                            (i + 2 < in.size() ? static_cast<std::uint32_t>(static_cast<unsigned char>(in[i + 2])) : 0);
    out += table[(n >> 18) & 63];
    out += table[(n >> 12) & 63];
    out += i + 1 < in.size() ? table[(n >> 6) & 63] : '=';
    out += i + 2 < in.size() ? table[n & 63] : '=';
  }
  return out;
}

std::string num(double v, int decimals = 1) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// A round step for about `ticks` divisions of span.
double nice_step(double span, int ticks) {
  const double raw = span / ticks, mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (raw <= m * mag) return m * mag;
  return 10 * mag;
}

// A series' figures for a summary table: the mean's range of motion and its peak.
std::string summary_figure(const json& s) {
  const std::vector<double> mean = s["mean"];
  const auto [lo, hi] = std::minmax_element(mean.begin(), mean.end());
  return num(*lo, 2) + " to " + num(*hi, 2);
}

}  // namespace

std::string cycle_plot_svg(const std::string& title, const json& series, const json& percent) {
  constexpr double W = 480, H = 260, left = 56, right = 12, top = 28, bottom = 40;
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& s : series) {
    for (const auto& stride : s["strides"])
      for (const auto& v : stride) lo = std::min(lo, v.get<double>()), hi = std::max(hi, v.get<double>());
    for (std::size_t k = 0; k < s["mean"].size(); ++k) {
      const double m = s["mean"][k], sd = s["sd"][k];
      lo = std::min(lo, m - sd), hi = std::max(hi, m + sd);
    }
  }
  if (!(hi > lo)) hi = lo + 1;
  const double step = nice_step(hi - lo, 5);
  lo = std::floor(lo / step) * step, hi = std::ceil(hi / step) * step;
  auto X = [&](double p) { return left + (W - left - right) * p / 100.0; };
  auto Y = [&](double v) { return top + (H - top - bottom) * (hi - v) / (hi - lo); };
  auto path = [&](const std::vector<double>& v) {
    std::string d;
    for (std::size_t k = 0; k < v.size(); ++k) d += (k ? " L" : "M") + num(X(percent[k].get<double>())) + "," + num(Y(v[k]));
    return d;
  };
  const std::string unit = series.empty() ? "" : series[0].value("unit", "");
  std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(W, 0) + "\" height=\"" + num(H, 0) + "\" viewBox=\"0 0 " + num(W, 0) +
                    " " + num(H, 0) + "\" font-family=\"sans-serif\" font-size=\"11\">";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>";
  svg += "<text x=\"" + num(left) + "\" y=\"16\" font-size=\"13\" font-weight=\"bold\">" + escape_html(title) + (unit.empty() ? "" : " (" + escape_html(unit) + ")") + "</text>";
  for (double v = lo; v <= hi + step / 2; v += step) {
    svg += "<line x1=\"" + num(left) + "\" x2=\"" + num(W - right) + "\" y1=\"" + num(Y(v)) + "\" y2=\"" + num(Y(v)) + "\" stroke=\"#e5e7eb\"/>";
    svg += "<text x=\"" + num(left - 4) + "\" y=\"" + num(Y(v) + 4) + "\" text-anchor=\"end\">" + num(std::abs(v) < step / 1e6 ? 0.0 : v, step < 1 ? 2 : 0) + "</text>";
  }
  for (int p = 0; p <= 100; p += 20) {
    svg += "<line x1=\"" + num(X(p)) + "\" x2=\"" + num(X(p)) + "\" y1=\"" + num(top) + "\" y2=\"" + num(H - bottom) + "\" stroke=\"#e5e7eb\"/>";
    svg += "<text x=\"" + num(X(p)) + "\" y=\"" + num(H - bottom + 14) + "\" text-anchor=\"middle\">" + std::to_string(p) + "</text>";
  }
  svg += "<text x=\"" + num((left + W - right) / 2) + "\" y=\"" + num(H - 6) + "\" text-anchor=\"middle\">% of gait cycle</text>";
  for (const auto& s : series) {
    const std::string color = s.value("side", "r") == "l" ? "#dc2626" : "#2563eb";
    const std::vector<double> mean = s["mean"], sd = s["sd"];
    std::vector<double> upper(mean.size()), lower(mean.size());
    for (std::size_t k = 0; k < mean.size(); ++k) upper[k] = mean[k] + sd[k], lower[k] = mean[k] - sd[k];
    std::string band = path(upper);
    for (std::size_t k = lower.size(); k-- > 0;) band += " L" + num(X(percent[k].get<double>())) + "," + num(Y(lower[k]));
    svg += "<path d=\"" + band + " Z\" fill=\"" + color + "\" fill-opacity=\"0.18\" stroke=\"none\"/>";
    for (const auto& stride : s["strides"])
      svg += "<path d=\"" + path(stride.get<std::vector<double>>()) + "\" fill=\"none\" stroke=\"" + color + "\" stroke-opacity=\"0.45\" stroke-width=\"1\"/>";
    svg += "<path d=\"" + path(mean) + "\" fill=\"none\" stroke=\"" + color + "\" stroke-width=\"2.5\"><title>" + escape_html(s["name"].get<std::string>()) +
           " mean of " + std::to_string(s["strides"].size()) + " strides</title></path>";
  }
  svg += "</svg>";
  return svg;
}

std::string trial_report_html(const TrialRecord& t, const ModelRecord* model, const json& cycles) {
  std::string h = "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>" + escape_html(t.name) +
                  " - cpgait report</title><style>"
                  "body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#111827}h1{margin-bottom:0}"
                  "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #d1d5db;padding:4px 8px;text-align:left;vertical-align:top}"
                  ".muted{color:#6b7280}.plots{display:flex;flex-wrap:wrap;gap:8px}.warn{color:#92400e}pre{white-space:pre-wrap;font-size:11px}"
                  ".legend span{margin-right:1.5em}.r{color:#2563eb}.l{color:#dc2626}"
                  "</style></head><body>";
  h += "<h1>" + escape_html(t.name) + "</h1><p class=\"muted\">cpgait trial " + escape_html(t.id) + ", uploaded " + escape_html(t.created_at) +
       ", status " + escape_html(t.status) + (model ? ", model " + escape_html(model->name) : "") + ". Report made " + now_iso8601() + ".</p>";
  if (!t.error.is_null()) h += "<p class=\"warn\">Error: " + escape_html(t.error.value("message", "")) + "</p>";

  h += "<h2>Stages</h2><table><tr><th>stage</th><th>state</th><th>seconds</th><th>figures</th></tr>";
  for (const auto& s : t.stages) {
    std::string figures;
    for (const auto& [key, value] : s.summary.items())
      if (value.is_number() || value.is_string() || value.is_boolean())
        figures += escape_html(key) + ": " + escape_html(value.is_number_float() ? num(value.get<double>(), 4) : value.dump()) + "<br>";
    h += "<tr><td>" + escape_html(s.name) + "</td><td>" + escape_html(s.state) + "</td><td>" + num(s.seconds, 3) + "</td><td>" + figures + "</td></tr>";
  }
  h += "</table>";

  std::vector<std::string> warnings;
  if (model)
    for (const auto& w : model->warnings) warnings.push_back("model: " + (w.is_string() ? w.get<std::string>() : w.dump()));
  for (const auto& s : t.stages)
    if (s.summary.contains("warnings"))
      for (const auto& w : s.summary["warnings"]) warnings.push_back(s.name + ": " + (w.is_string() ? w.get<std::string>() : w.dump()));
  h += "<h2>Warnings</h2>";
  if (warnings.empty()) h += "<p class=\"muted\">None.</p>";
  else {
    h += "<ul>";
    for (const auto& w : warnings) h += "<li class=\"warn\">" + escape_html(w) + "</li>";
    h += "</ul>";
  }

  const bool strides = !cycles.is_null() && std::any_of(cycles["panels"].begin(), cycles["panels"].end(), [](const json& p) { return !p["series"].empty(); });
  if (!strides) h += "<h2>Gait cycles</h2><p class=\"muted\">No full stride (two heel strikes of one foot) in the trial's kinematics.</p>";
  if (strides) {
    h += "<h2>Gait cycles</h2><p class=\"legend\"><span class=\"r\">&#9644; right</span><span class=\"l\">&#9644; left</span>"
         "<span class=\"muted\">thin: each stride; bold: their mean; band: mean &plusmn; SD</span></p><p class=\"muted\">Heel strikes: right " +
         escape_html(cycles["heel_strike_source"].value("r", "none")) + ", left " + escape_html(cycles["heel_strike_source"].value("l", "none")) + ".</p>";
    // The quantities a gait report shows first, where the trial has them.
    const std::vector<std::pair<std::string, std::vector<std::string>>> shown = {
        {"kinematics", {"pelvis_tilt", "hip_flexion", "hip_adduction", "knee_angle", "ankle_angle", "subtalar_angle"}},
        {"moments", {"hip_flexion", "knee_angle", "ankle_angle"}},
        {"activations", {"glut_max1", "rect_fem", "vas_int", "bifemsh", "med_gas", "soleus", "tib_ant"}}};
    for (const auto& [panel_name, quantities] : shown)
      for (const auto& panel : cycles["panels"]) {
        if (panel["name"] != panel_name) continue;
        std::string images, table;
        for (const auto& q : quantities) {
          json chosen = json::array();
          for (const auto& s : panel["series"]) {
            const std::string base = column_quantity(s["name"]);
            if (base == q || base == q + "_r" || base == q + "_l") chosen.push_back(s);
          }
          if (chosen.empty()) continue;
          const std::string title = q + (panel_name == "moments" ? " moment" : "");
          images += "<img alt=\"" + escape_html(title) + "\" width=\"480\" height=\"260\" src=\"data:image/svg+xml;base64," +
                    base64(cycle_plot_svg(title, chosen, cycles["percent"])) + "\">";
          for (const auto& s : chosen)
            table += "<tr><td>" + escape_html(s["name"].get<std::string>()) + "</td><td>" + std::to_string(s["strides"].size()) + "</td><td>" +
                     summary_figure(s) + " " + escape_html(s.value("unit", "")) + "</td></tr>";
        }
        if (images.empty()) continue;
        h += "<h3>" + escape_html(panel_name) + "</h3><div class=\"plots\">" + images + "</div><table><tr><th>series</th><th>strides</th><th>mean's range</th></tr>" +
             table + "</table>";
      }
  }
  h += "<h2>Options</h2><pre>" + escape_html(json_text(t.options, 2)) + "</pre>";
  h += "<p class=\"muted\">Made by cpgait. Results and every file of the trial: /api/v1/trials/" + escape_html(t.id) + ".</p></body></html>\n";
  return h;
}

}  // namespace cpgait::services
