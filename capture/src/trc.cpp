#include "cpgait/capture/trc.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <stdexcept>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait {
namespace {

// Splits a TRC line: tab separated when it holds a tab (blank cells are meaningful), otherwise on
// spaces (some writers use them; such files cannot hold blank cells).
std::vector<std::string_view> split_trc(std::string_view line) {
  return line.find('\t') != std::string_view::npos ? text::split_tabs(line) : text::split_ws(line);
}

}  // namespace

double metres_per_unit(std::string_view units) {
  const std::string u = text::lower(text::trim(units));
  if (u == "mm") return 1e-3;
  if (u == "cm") return 1e-2;
  if (u == "m") return 1.0;
  throw std::invalid_argument("unknown length unit '" + std::string(units) + "': expected mm, cm or m");
}

int MarkerTrial::marker_index(std::string_view name) const {
  for (int i = 0; i < num_markers(); ++i)
    if (marker_names[i] == name) return i;
  return -1;
}

std::vector<MarkerGap> MarkerTrial::gaps() const {
  std::vector<MarkerGap> out;
  for (int m = 0; m < num_markers(); ++m) {
    int f = 0;
    while (f < num_frames()) {
      if (!position_m(f, m).array().isNaN().any()) {
        ++f;
        continue;
      }
      MarkerGap gap{marker_names[m], f, f, time_s[f], time_s[f]};
      while (f < num_frames() && position_m(f, m).array().isNaN().any()) ++f;
      gap.last_frame = f - 1;
      gap.end_time_s = time_s[f - 1];
      out.push_back(gap);
    }
  }
  return out;
}

MarkerTrial read_trc(const std::string& path, const TrcReadOptions& options) {
  // Files and uploads go through the same parser.
  return parse_trc(text::read_file(path, options.max_bytes), path, options);
}

MarkerTrial parse_trc(std::string_view content, const std::string& name,
                      const TrcReadOptions& options) {
  if (content.size() > options.max_bytes)
    throw InputError(name, 0, "", "upload is over the limit of " + std::to_string(options.max_bytes) +
                                      " bytes");
  const text::Lines lines = text::split_lines(content, name);
  const auto& L = lines.lines;
  auto fail = [&](int line_index, const std::string& field, const std::string& msg) -> InputError {
    return InputError(name, line_index + 1, field, msg);
  };
  if (L.empty()) throw fail(0, "", "file is empty: expected a TRC header ('PathFileType ...')");
  if (text::split_ws(L[0]).empty() || text::lower(text::split_ws(L[0])[0]) != "pathfiletype")
    throw fail(0, "PathFileType", "expected a TRC file starting with 'PathFileType'");
  if (L.size() < 5)
    throw fail(static_cast<int>(L.size()) - 1, "",
               "file ends inside the header: a TRC needs 5 header lines (PathFileType, keys, values, "
               "marker names, X/Y/Z labels)");

  MarkerTrial trial;
  trial.name = name;

  // Lines 2 and 3: header keys and their values.
  // Tab-separated cells keep empty optional values in place; when the two rows disagree (OpenSim's
  // tutorial files put two tabs between values), runs of tabs and spaces separate them instead.
  auto keys = split_trc(L[1]);
  auto values = split_trc(L[2]);
  if (keys.size() != values.size()) {
    keys = text::split_ws(L[1]);
    values = text::split_ws(L[2]);
  }
  std::map<std::string, std::string> header;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const std::string key = text::lower(text::trim(keys[i]));
    if (key.empty()) continue;
    if (i >= values.size())
      throw fail(2, std::string(text::trim(keys[i])), "no value under this header key");
    header[key] = std::string(text::trim(values[i]));
  }
  auto number = [&](const char* key, bool required, double fallback) {
    auto it = header.find(key);
    if (it == header.end()) {
      if (required) throw fail(1, key, "missing header key");
      return fallback;
    }
    double v;
    if (!text::parse_double(it->second, v) || !std::isfinite(v))
      throw fail(2, key, "expected a number, found '" + it->second + "'");
    return v;
  };
  trial.data_rate_hz = number("datarate", true, 0);
  if (trial.data_rate_hz <= 0) throw fail(2, "DataRate", "must be positive");
  trial.camera_rate_hz = number("camerarate", false, trial.data_rate_hz);
  const double num_frames_header = number("numframes", true, 0);
  const double num_markers_header = number("nummarkers", true, 0);
  trial.orig_data_rate_hz = number("origdatarate", false, trial.data_rate_hz);
  const double orig_start = number("origdatastartframe", false, 1);
  if (!(std::abs(orig_start) <= 1e9)) throw fail(2, "OrigDataStartFrame", "implausible frame number");
  trial.orig_data_start_frame = static_cast<int>(orig_start);
  if (num_markers_header < 0 || num_markers_header > 100000 || num_frames_header < 0 || num_frames_header > 1e9)
    throw fail(2, "NumMarkers", "implausible NumMarkers/NumFrames");
  auto units_it = header.find("units");
  if (units_it == header.end()) throw fail(1, "Units", "missing header key (expected mm, cm or m)");
  double scale;
  try {
    scale = metres_per_unit(units_it->second);
  } catch (const std::invalid_argument& e) {
    throw fail(2, "Units", e.what());
  }
  trial.units_in_file = text::lower(units_it->second);

  // Line 4: Frame#, Time, then marker names (each followed by two blank cells when tab separated).
  const auto name_cells = split_trc(L[3]);
  if (name_cells.size() < 2) throw fail(3, "Frame#", "expected 'Frame#<tab>Time<tab>marker names'");
  for (std::size_t i = 2; i < name_cells.size(); ++i) {
    const auto n = text::trim(name_cells[i]);
    if (!n.empty()) trial.marker_names.emplace_back(n);
  }
  const int num_markers = trial.num_markers();
  if (num_markers != static_cast<int>(num_markers_header))
    throw fail(3, "NumMarkers",
               "header says " + std::to_string(static_cast<long long>(num_markers_header)) +
                   " markers but the name line lists " + std::to_string(num_markers));
  {
    std::map<std::string_view, int> seen;
    for (const auto& m : trial.marker_names)
      if (seen[m]++) throw fail(3, m, "marker name appears twice");
  }

  // Data starts after the X/Y/Z label line; blank lines between are skipped.
  std::size_t first = 5;
  while (first < L.size() && text::trim(L[first]).empty()) ++first;

  const std::size_t expected_cells = 2 + 3 * static_cast<std::size_t>(num_markers);
  std::vector<double> pos;
  // Reserve from the file size, not the header, so a lying NumFrames cannot allocate unbounded memory.
  pos.reserve(std::min<std::size_t>(L.size() - first, static_cast<std::size_t>(num_frames_header)) *
              3 * num_markers);
  bool extra_cells_warned = false;
  for (std::size_t li = first; li < L.size(); ++li) {
    if (text::trim(L[li]).empty()) continue;  // blank lines at the end
    auto cells = split_trc(L[li]);
    while (cells.size() > expected_cells && text::trim(cells.back()).empty()) cells.pop_back();
    const int line_index = static_cast<int>(li);
    if (cells.size() > expected_cells) {
      if (!extra_cells_warned)
        trial.warnings.push_back(name + ":" + std::to_string(li + 1) + ": " + std::to_string(cells.size() - expected_cells) +
                                 " cell(s) beyond the listed markers' columns are ignored");
      extra_cells_warned = true;
      cells.resize(expected_cells);
    }
    if (cells.size() < expected_cells) {
      const std::size_t m = cells.size() < 2 ? 0 : (cells.size() - 2) / 3;
      throw fail(line_index, m < trial.marker_names.size() ? trial.marker_names[m] : "Time",
                 "row ends after " + std::to_string(cells.size()) + " of " + std::to_string(expected_cells) +
                     " cells (truncated file?)");
    }
    long long frame;
    double frame_d;
    if (text::trim(cells[0]).empty()) {
      frame = trial.frame_numbers.empty() ? 1 : trial.frame_numbers.back() + 1;  // a writer that leaves Frame# blank
    } else if (!text::parse_int(cells[0], frame)) {
      // Some writers put the frame number as a float.
      if (!text::parse_double(cells[0], frame_d))
        throw fail(line_index, "Frame#", "expected a frame number, found '" + std::string(cells[0]) + "'");
      frame = static_cast<long long>(frame_d);
    }
    double t;
    if (!text::parse_double(cells[1], t) || !std::isfinite(t))
      throw fail(line_index, "Time", "expected a time in seconds, found '" + std::string(cells[1]) + "'");
    if (!trial.time_s.empty() && t <= trial.time_s.back())
      throw fail(line_index, "Time", "time " + std::to_string(t) + " does not increase");
    trial.frame_numbers.push_back(static_cast<int>(frame));
    trial.time_s.push_back(t);
    for (int m = 0; m < num_markers; ++m) {
      double xyz[3];
      int blanks = 0;
      for (int a = 0; a < 3; ++a) {
        const auto cell = text::trim(cells[2 + 3 * m + a]);
        if (cell.empty()) {
          xyz[a] = std::numeric_limits<double>::quiet_NaN();
          ++blanks;
        } else if (!text::parse_double(cell, xyz[a]) || std::isinf(xyz[a])) {
          throw fail(line_index, trial.marker_names[m] + "." + "XYZ"[a],
                     "expected a number or a blank cell, found '" + std::string(cell) + "'");
        }
      }
      if (blanks != 0 && blanks != 3)
        trial.warnings.push_back(name + ":" + std::to_string(li + 1) + ": " + trial.marker_names[m] +
                                 ": only some coordinates blank; marker treated as missing");
      const bool missing = std::isnan(xyz[0]) || std::isnan(xyz[1]) || std::isnan(xyz[2]);
      for (int a = 0; a < 3; ++a)
        pos.push_back(missing ? std::numeric_limits<double>::quiet_NaN() : xyz[a] * scale);
    }
  }
  const int frames = trial.num_frames();
  if (frames == 0) throw fail(static_cast<int>(L.size()) - 1, "", "no data rows after the header");
  // Compared as doubles: a hostile header's NumFrames may not fit in an int.
  // As OpenSim: the rows are the data; a header that disagrees is reported, not obeyed.
  if (frames != num_frames_header)
    trial.warnings.push_back(name + ": NumFrames says " +
                             std::to_string(static_cast<long long>(num_frames_header)) + " but " +
                             std::to_string(frames) + " rows were read");
  trial.orig_num_frames = static_cast<int>(number("orignumframes", false, frames));
  trial.positions_m = Eigen::Map<Eigen::Matrix3Xd>(pos.data(), 3, static_cast<Eigen::Index>(pos.size() / 3));
  return trial;
}

std::string format_trc(const MarkerTrial& trial, const std::string& units) {
  const double per_unit = 1.0 / metres_per_unit(units);
  std::string out;
  char buf[64];
  out += "PathFileType\t4\t(X/Y/Z)\t" + trial.name + "\n";
  out += "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n";
  std::snprintf(buf, sizeof buf, "%.6g\t%.6g\t%d\t%d\t", trial.data_rate_hz, trial.camera_rate_hz,
                trial.num_frames(), trial.num_markers());
  out += buf + units;
  std::snprintf(buf, sizeof buf, "\t%.6g\t%d\t%d\n", trial.orig_data_rate_hz, trial.orig_data_start_frame,
                trial.orig_num_frames > 0 ? trial.orig_num_frames : trial.num_frames());
  out += buf;
  out += "Frame#\tTime";
  for (const auto& m : trial.marker_names) out += "\t" + m + "\t\t";
  out += "\n\t";
  for (int m = 1; m <= trial.num_markers(); ++m) {
    std::snprintf(buf, sizeof buf, "\tX%d\tY%d\tZ%d", m, m, m);
    out += buf;
  }
  out += "\n\n";
  for (int f = 0; f < trial.num_frames(); ++f) {
    const int frame_number = f < static_cast<int>(trial.frame_numbers.size()) ? trial.frame_numbers[f] : f + 1;
    std::snprintf(buf, sizeof buf, "%d\t%.10g", frame_number, trial.time_s[f]);
    out += buf;
    for (int m = 0; m < trial.num_markers(); ++m) {
      const auto p = trial.position_m(f, m);
      for (int a = 0; a < 3; ++a) {
        if (std::isnan(p[a])) {
          out += "\t";
        } else {
          std::snprintf(buf, sizeof buf, "\t%.10g", p[a] * per_unit);
          out += buf;
        }
      }
    }
    out += "\n";
  }
  return out;
}

void write_trc(const MarkerTrial& trial, const std::string& path, const std::string& units) {
  const std::string text = format_trc(trial, units);
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << text;
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace cpgait
