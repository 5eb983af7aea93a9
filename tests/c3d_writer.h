#pragma once
// A minimal C3D writer for tests: the round trip through every processor format, and trials written
// as a lab would export them (Z-up, float) for the commands that read C3D.
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "cpgait/capture/trc.h"

namespace cpgait::testing {

// Header, parameter records and data words in a processor format (84 Intel, 85 DEC, 86 MIPS).
struct C3dWriter {
  int processor = 84;
  std::string out;

  void u8(int v) { out.push_back(static_cast<char>(v & 0xff)); }
  void i16(int v) {
    const auto w = static_cast<std::uint16_t>(v);
    if (processor == 86) u8(w >> 8), u8(w);
    else u8(w), u8(w >> 8);
  }
  void f32(float v) {
    std::uint32_t w;
    if (processor == 85) {
      const float v4 = v * 4.0f;  // DEC: bias 128, hidden bit at 0.1: the IEEE bits of 4v, words swapped
      std::memcpy(&w, &v4, 4);
      u8(static_cast<int>(w >> 16)), u8(static_cast<int>(w >> 24)), u8(static_cast<int>(w)), u8(static_cast<int>(w >> 8));
      return;
    }
    std::memcpy(&w, &v, 4);
    if (processor == 86) u8(static_cast<int>(w >> 24)), u8(static_cast<int>(w >> 16)), u8(static_cast<int>(w >> 8)), u8(static_cast<int>(w));
    else u8(static_cast<int>(w)), u8(static_cast<int>(w >> 8)), u8(static_cast<int>(w >> 16)), u8(static_cast<int>(w >> 24));
  }
  void pad() { out.resize((out.size() + 511) / 512 * 512, '\0'); }

  // One parameter record (group id > 0) with its link to the next.
  void parameter(int group, const std::string& name, int type, const std::vector<int>& dims, const std::function<void()>& data) {
    u8(static_cast<int>(name.size())), u8(group);
    out += name;
    const std::size_t link = out.size();
    i16(0);
    u8(type), u8(static_cast<int>(dims.size()));
    for (int d : dims) u8(d);
    data();
    u8(0);  // no description
    const int next = static_cast<int>(out.size() - link);
    const std::string saved = out;
    out.resize(link);
    i16(next);
    out += saved.substr(link + 2);
  }
  void group(int id, const std::string& name) {
    u8(static_cast<int>(name.size())), u8(-id);
    out += name;
    i16(3), u8(0);
  }
};


// The header (Intel, float, mm) and the POINT group of a trial with `channels` analog channels at
// `samples` a frame, its parameters in `parameter_blocks` blocks.
inline void write_float_header_and_points(C3dWriter& w, const MarkerTrial& t, int channels, int samples, int parameter_blocks) {
  const int points = t.num_markers();
  std::size_t label_width = 1;
  for (const auto& n : t.marker_names) label_width = std::max(label_width, n.size());
  w.u8(2), w.u8(0x50);
  w.i16(points), w.i16(channels * samples), w.i16(1), w.i16(t.num_frames()), w.i16(0);
  w.f32(-1.0f);
  w.i16(2 + parameter_blocks), w.i16(samples);
  w.f32(static_cast<float>(t.data_rate_hz));
  w.pad();
  w.u8(1), w.u8(0x50), w.u8(parameter_blocks), w.u8(84);
  w.group(1, "POINT");
  w.parameter(1, "USED", 2, {}, [&] { w.i16(points); });
  w.parameter(1, "SCALE", 4, {}, [&] { w.f32(-1.0f); });
  w.parameter(1, "RATE", 4, {}, [&] { w.f32(static_cast<float>(t.data_rate_hz)); });
  w.parameter(1, "UNITS", -1, {2}, [&] { w.out += "mm"; });
  w.parameter(1, "LABELS", -1, {static_cast<int>(label_width), points}, [&] {
    for (const auto& n : t.marker_names) w.out += n + std::string(label_width - n.size(), ' ');
  });
}

// A marker trial as an Intel float C3D in mm from a Z-up lab: OpenSim's (x, y, z) stored as (x, -z, y).
inline std::string format_c3d_z_up(const MarkerTrial& t) {
  const int points = t.num_markers(), frames = t.num_frames();
  const int parameter_blocks = 4, data_block = 2 + parameter_blocks;
  C3dWriter w;
  write_float_header_and_points(w, t, 0, 0, parameter_blocks);
  w.u8(0), w.u8(0);
  w.out.resize(static_cast<std::size_t>(data_block - 1) * 512, '\0');
  for (int f = 0; f < frames; ++f)
    for (int m = 0; m < points; ++m) {
      const auto p = t.position_m(f, m) * 1000.0;
      const bool missing = !p.allFinite();
      w.f32(missing ? 0.0f : static_cast<float>(p.x())), w.f32(missing ? 0.0f : static_cast<float>(-p.z())), w.f32(missing ? 0.0f : static_cast<float>(p.y()));
      w.f32(missing ? -1.0f : 1.0f);
    }
  w.pad();
  return w.out;
}

// The same trial with OpenSim GRF columns as force plates (type 2, one per column prefix, e.g.
// "ground_force_" and "1_ground_force_" with their "ground_torque_"), each 4 x 2 m around the lab's
// origin; the GRF rows are the analog samples in order (`samples` per frame, the last row repeated).
inline std::string format_c3d_z_up_with_plates(const MarkerTrial& t, const Eigen::MatrixXd& grf_rows, const std::vector<std::string>& labels,
                                               const std::vector<std::string>& prefixes, int samples) {
  const int points = t.num_markers(), frames = t.num_frames(), plates = static_cast<int>(prefixes.size()), channels = 6 * plates;
  auto col = [&](const std::string& name) {
    for (std::size_t i = 0; i < labels.size(); ++i)
      if (labels[i] == name) return static_cast<int>(i);
    return -1;
  };
  const int parameter_blocks = 6, data_block = 2 + parameter_blocks;
  C3dWriter w;
  write_float_header_and_points(w, t, channels, samples, parameter_blocks);
  w.group(2, "ANALOG");
  w.parameter(2, "USED", 2, {}, [&] { w.i16(channels); });
  w.parameter(2, "RATE", 4, {}, [&] { w.f32(static_cast<float>(t.data_rate_hz * samples)); });
  w.parameter(2, "GEN_SCALE", 4, {}, [&] { w.f32(1.0f); });
  w.parameter(2, "SCALE", 4, {channels}, [&] { for (int c = 0; c < channels; ++c) w.f32(1.0f); });
  w.parameter(2, "OFFSET", 2, {channels}, [&] { for (int c = 0; c < channels; ++c) w.i16(0); });
  w.parameter(2, "UNITS", -1, {3, channels}, [&] { for (int c = 0; c < channels; ++c) w.out += c % 6 < 3 ? "N  " : "Nmm"; });
  w.group(3, "FORCE_PLATFORM");
  w.parameter(3, "USED", 2, {}, [&] { w.i16(plates); });
  w.parameter(3, "TYPE", 2, {plates}, [&] { for (int p = 0; p < plates; ++p) w.i16(2); });
  w.parameter(3, "CORNERS", 4, {3, 4, plates}, [&] {
    for (int p = 0; p < plates; ++p)
      for (float v : {3000.f, 1000.f, 0.f, 3000.f, -1000.f, 0.f, -1000.f, -1000.f, 0.f, -1000.f, 1000.f, 0.f}) w.f32(v);
  });
  w.parameter(3, "ORIGIN", 4, {3, plates}, [&] { for (int k = 0; k < 3 * plates; ++k) w.f32(0.0f); });
  w.parameter(3, "CHANNEL", 2, {6, plates}, [&] { for (int c = 1; c <= channels; ++c) w.i16(c); });
  w.u8(0), w.u8(0);
  w.out.resize(static_cast<std::size_t>(data_block - 1) * 512, '\0');
  // Plate axes: x = lab y, y = lab x, z = -lab z; centre (1, 0, 0) m. Lab = OpenSim's (x, -z, y).
  auto lab = [](double x, double y, double z) { return std::array<double, 3>{x, -z, y}; };
  for (int f = 0; f < frames; ++f) {
    for (int m = 0; m < points; ++m) {
      const auto p = t.position_m(f, m) * 1000.0;
      const bool missing = !p.allFinite();
      w.f32(missing ? 0.0f : static_cast<float>(p.x())), w.f32(missing ? 0.0f : static_cast<float>(-p.z())), w.f32(missing ? 0.0f : static_cast<float>(p.y()));
      w.f32(missing ? -1.0f : 1.0f);
    }
    for (int s = 0; s < samples; ++s) {
      const Eigen::Index row = std::min<Eigen::Index>(static_cast<Eigen::Index>(f) * samples + s, grf_rows.rows() - 1);
      for (const auto& prefix : prefixes) {
        auto v = [&](const std::string& name) { const int c = col(name); return c < 0 ? 0.0 : grf_rows(row, c); };
        const std::string torque = prefix.substr(0, prefix.find("ground_force_")) + "ground_torque_";
        const auto F = lab(v(prefix + "vx"), v(prefix + "vy"), v(prefix + "vz"));
        const auto P = lab(v(prefix + "px"), v(prefix + "py"), v(prefix + "pz"));
        const auto T = lab(v(torque + "x"), v(torque + "y"), v(torque + "z"));
        // Plate frame: (lab y, lab x, -lab z); point from the centre on the surface; moment about the centre.
        const double fp[3] = {F[1], F[0], -F[2]}, rp[3] = {P[1] - 0.0, P[0] - 1.0, 0.0}, tp[3] = {T[1], T[0], -T[2]};
        const double mp[3] = {rp[1] * fp[2] - rp[2] * fp[1] + tp[0], rp[2] * fp[0] - rp[0] * fp[2] + tp[1], rp[0] * fp[1] - rp[1] * fp[0] + tp[2]};
        for (double c : fp) w.f32(static_cast<float>(c));
        for (double c : mp) w.f32(static_cast<float>(1000.0 * c));
      }
    }
  }
  w.pad();
  return w.out;
}

}  // namespace cpgait::testing
