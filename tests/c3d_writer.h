#pragma once
// A minimal C3D writer for tests: the round trip through every processor format, and trials written
// as a lab would export them (Z-up, float) for the commands that read C3D.
#include <algorithm>
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


// A marker trial as an Intel float C3D in mm from a Z-up lab: OpenSim's (x, y, z) stored as (x, -z, y).
inline std::string format_c3d_z_up(const MarkerTrial& t) {
  const int points = t.num_markers(), frames = t.num_frames();
  std::size_t label_width = 1;
  for (const auto& n : t.marker_names) label_width = std::max(label_width, n.size());
  C3dWriter w;
  w.u8(2), w.u8(0x50);
  w.i16(points), w.i16(0), w.i16(1), w.i16(frames), w.i16(0);
  w.f32(-1.0f);
  const int parameter_blocks = 4, data_block = 2 + parameter_blocks;
  w.i16(data_block), w.i16(0);
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

}  // namespace cpgait::testing
