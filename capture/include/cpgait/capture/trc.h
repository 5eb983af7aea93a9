#pragma once
// Marker trajectories in OpenSim's TRC format. Positions are metres inside, whatever the file said;
// a missing marker (blank cells) is NaN and listed in gaps().
#include <Eigen/Core>
#include <string>
#include <string_view>
#include <vector>

namespace cpgait {

struct MarkerGap {
  std::string marker;
  int first_frame = 0;  // 0-based frame indices, inclusive
  int last_frame = 0;
  double start_time_s = 0;
  double end_time_s = 0;
};

struct MarkerTrial {
  std::string name;                      // the file name the trial came from, for messages
  std::vector<std::string> marker_names;
  std::vector<double> time_s;
  std::vector<int> frame_numbers;        // the Frame# column as written
  // Column f * num_markers() + m holds marker m at frame f, in metres in the lab frame.
  Eigen::Matrix3Xd positions_m;

  double data_rate_hz = 0;
  double camera_rate_hz = 0;
  double orig_data_rate_hz = 0;
  int orig_data_start_frame = 1;
  int orig_num_frames = 0;
  std::string units_in_file = "m";        // "mm", "cm" or "m" as read; informational
  std::vector<std::string> warnings;

  int num_frames() const { return static_cast<int>(time_s.size()); }
  int num_markers() const { return static_cast<int>(marker_names.size()); }
  auto position_m(int frame, int marker) { return positions_m.col(frame * num_markers() + marker); }
  auto position_m(int frame, int marker) const {
    return positions_m.col(frame * num_markers() + marker);
  }
  int marker_index(std::string_view name) const;  // -1 when absent
  std::vector<MarkerGap> gaps() const;
};

struct TrcReadOptions {
  // Upper bound on the file size, so a hostile upload cannot exhaust memory.
  std::size_t max_bytes = std::size_t{1} << 30;
};

// Throws InputError naming the file, line and field for anything malformed.
MarkerTrial read_trc(const std::string& path, const TrcReadOptions& options = {});
MarkerTrial parse_trc(std::string_view content, const std::string& name,
                      const TrcReadOptions& options = {});

// Writes a TRC (tab separated, blank cells for NaN) in `units` ("mm", "cm" or "m").
void write_trc(const MarkerTrial& trial, const std::string& path, const std::string& units = "mm");
std::string format_trc(const MarkerTrial& trial, const std::string& units = "mm");

// Metres per unit of a TRC `Units` value; throws std::invalid_argument for anything else.
double metres_per_unit(std::string_view units);

}  // namespace cpgait
