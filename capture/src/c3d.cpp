#include "cpgait/capture/c3d.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait {
namespace {

constexpr std::size_t kBlock = 512;

// Bounds-checked reads in the file's processor format. Every read names its byte offset on failure.
class Bytes {
 public:
  Bytes(std::string_view data, const std::string& name) : data_(data), name_(name) {}
  C3dFile::Processor processor = C3dFile::Processor::kIntel;

  std::size_t size() const { return data_.size(); }
  [[noreturn]] void fail(std::size_t offset, std::string_view field, const std::string& message) const {
    throw InputError(name_, 0, std::string(field), "byte " + std::to_string(offset) + ": " + message);
  }
  void need(std::size_t offset, std::size_t n, std::string_view field) const {
    if (offset > data_.size() || n > data_.size() - offset)
      fail(offset, field, "the file ends at byte " + std::to_string(data_.size()) + ", " + std::to_string(n) + " more bytes expected");
  }
  std::uint8_t u8(std::size_t at, std::string_view field) const {
    need(at, 1, field);
    return static_cast<std::uint8_t>(data_[at]);
  }
  std::int8_t i8(std::size_t at, std::string_view field) const { return static_cast<std::int8_t>(u8(at, field)); }
  std::uint16_t u16(std::size_t at, std::string_view field) const {
    need(at, 2, field);
    const auto b0 = static_cast<std::uint8_t>(data_[at]), b1 = static_cast<std::uint8_t>(data_[at + 1]);
    return processor == C3dFile::Processor::kMips ? static_cast<std::uint16_t>(b0 << 8 | b1) : static_cast<std::uint16_t>(b1 << 8 | b0);
  }
  std::int16_t i16(std::size_t at, std::string_view field) const { return static_cast<std::int16_t>(u16(at, field)); }
  float f32(std::size_t at, std::string_view field) const {
    need(at, 4, field);
    std::uint8_t b[4];
    std::memcpy(b, data_.data() + at, 4);
    std::uint32_t w;
    if (processor == C3dFile::Processor::kMips) {
      w = std::uint32_t(b[0]) << 24 | std::uint32_t(b[1]) << 16 | std::uint32_t(b[2]) << 8 | b[3];
    } else if (processor == C3dFile::Processor::kIntel) {
      w = std::uint32_t(b[3]) << 24 | std::uint32_t(b[2]) << 16 | std::uint32_t(b[1]) << 8 | b[0];
    } else {
      // DEC (VAX F): two little-endian 16-bit words, the high word first, exponent bias 128 and the
      // hidden bit at 0.1 binary: IEEE's bits with the words swapped, divided by 4.
      w = std::uint32_t(b[1]) << 24 | std::uint32_t(b[0]) << 16 | std::uint32_t(b[3]) << 8 | b[2];
      if ((w & 0x7f800000u) == 0) return 0.0f;
    }
    float f;
    std::memcpy(&f, &w, 4);
    return processor == C3dFile::Processor::kDec ? f / 4.0f : f;
  }
  std::string text(std::size_t at, std::size_t n, std::string_view field) const {
    need(at, n, field);
    return std::string(data_.substr(at, n));
  }

 private:
  std::string_view data_;
  const std::string& name_;
};

std::string trim_right(std::string s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// The parameter section: groups (negative id) and parameters (positive id: their group's), linked by
// offsets; groups may follow their parameters.
std::vector<C3dParameter> read_parameters(const Bytes& in, std::size_t start) {
  const std::size_t blocks = in.u8(start + 2, "parameter blocks");
  const std::size_t end = std::min(in.size(), start + std::max<std::size_t>(blocks, 1) * kBlock);
  std::map<int, std::string> groups;
  std::vector<std::pair<int, C3dParameter>> params;
  std::size_t pos = start + 4;
  while (pos + 2 <= end) {
    const int chars = std::abs(in.i8(pos, "parameter name length"));
    const int id = in.i8(pos + 1, "parameter group id");
    if (chars == 0 || id == 0) break;
    const std::string name = in.text(pos + 2, static_cast<std::size_t>(chars), "parameter name");
    const std::size_t link = pos + 2 + static_cast<std::size_t>(chars);
    const int next = in.i16(link, name + " (offset to the next record)");
    if (id < 0) {
      groups[-id] = trim_right(name);
    } else {
      C3dParameter p;
      p.name = trim_right(name);
      p.type = in.i8(link + 2, p.name + " (data type)");
      if (p.type != -1 && p.type != 1 && p.type != 2 && p.type != 4)
        in.fail(link + 2, p.name, "data type " + std::to_string(p.type) + " (expected -1, 1, 2 or 4)");
      const int ndims = in.u8(link + 3, p.name + " (dimensions)");
      std::size_t count = 1;
      for (int d = 0; d < ndims; ++d) {
        p.dimensions.push_back(in.u8(link + 4 + static_cast<std::size_t>(d), p.name + " (dimensions)"));
        count *= static_cast<std::size_t>(p.dimensions.back());
        if (count > in.size()) in.fail(link + 3, p.name, "dimensions that hold more values than the file has bytes");
      }
      const std::size_t data = link + 4 + static_cast<std::size_t>(ndims), width = static_cast<std::size_t>(std::abs(p.type));
      in.need(data, count * width, p.name);
      if (p.type == -1) {
        const std::size_t length = ndims ? static_cast<std::size_t>(p.dimensions[0]) : 1;
        for (std::size_t s = 0; length && s < count / length; ++s) p.strings.push_back(trim_right(in.text(data + s * length, length, p.name)));
      } else {
        p.numbers.reserve(count);
        for (std::size_t k = 0; k < count; ++k) {
          const std::size_t at = data + k * width;
          p.numbers.push_back(p.type == 1 ? in.u8(at, p.name) : p.type == 2 ? in.i16(at, p.name) : in.f32(at, p.name));
        }
      }
      params.emplace_back(id, std::move(p));
    }
    if (next <= 0) break;
    pos = link + static_cast<std::size_t>(next);
  }
  std::vector<C3dParameter> out;
  for (auto& [id, p] : params) {
    p.group = groups.count(id) ? groups[id] : "GROUP" + std::to_string(id);
    out.push_back(std::move(p));
  }
  return out;
}

double number(const C3dFile& f, std::string_view group, std::string_view name, double fallback, std::size_t index = 0) {
  const C3dParameter* p = f.parameter(group, name);
  return p && p->numbers.size() > index ? p->numbers[index] : fallback;
}

// Labels from GROUP:LABELS, then LABELS2, LABELS3, ... (files with more than 255 of them).
std::vector<std::string> labels(const C3dFile& f, std::string_view group, std::string_view base, int count) {
  std::vector<std::string> out;
  for (int k = 1; static_cast<int>(out.size()) < count; ++k) {
    const C3dParameter* p = f.parameter(group, k == 1 ? std::string(base) : std::string(base) + std::to_string(k));
    if (!p) break;
    for (const auto& s : p->strings) out.push_back(s);
  }
  out.resize(static_cast<std::size_t>(count));
  return out;
}

}  // namespace

const C3dParameter* C3dFile::parameter(std::string_view group, std::string_view name) const {
  for (const auto& p : parameters)
    if (p.group == group && p.name == name) return &p;
  return nullptr;
}

bool looks_like_c3d(std::string_view bytes) { return bytes.size() >= kBlock && static_cast<std::uint8_t>(bytes[1]) == 0x50; }

namespace {
// EVENT:USED events from TIMES (minutes, seconds pairs), LABELS and CONTEXTS.
void read_events(C3dFile& f) {
  const C3dParameter* used = f.parameter("EVENT", "USED");
  const C3dParameter* times = f.parameter("EVENT", "TIMES");
  if (!used || used->numbers.empty() || used->numbers[0] <= 0 || !times) return;
  const std::size_t n = static_cast<std::size_t>(used->numbers[0]);
  if (times->numbers.size() < 2 * n)
    throw InputError(f.name, 0, "EVENT:TIMES", "expected " + std::to_string(2 * n) + " numbers (minutes, seconds) for EVENT:USED events");
  const C3dParameter* labels = f.parameter("EVENT", "LABELS");
  const C3dParameter* contexts = f.parameter("EVENT", "CONTEXTS");
  for (std::size_t i = 0; i < n; ++i) {
    C3dEvent e;
    e.time_s = 60.0 * times->numbers[2 * i] + times->numbers[2 * i + 1];
    if (!std::isfinite(e.time_s)) throw InputError(f.name, 0, "EVENT:TIMES", "event " + std::to_string(i + 1) + "'s time is not finite");
    if (labels && i < labels->strings.size()) e.label = labels->strings[i];
    if (contexts && i < contexts->strings.size()) e.context = contexts->strings[i];
    f.events.push_back(e);
  }
  std::stable_sort(f.events.begin(), f.events.end(), [](const C3dEvent& a, const C3dEvent& b) { return a.time_s < b.time_s; });
}
}  // namespace

C3dFile parse_c3d(std::string_view data, const std::string& name) {
  Bytes in(data, name);
  C3dFile f;
  f.name = name;
  f.markers.name = name;
  if (data.size() < kBlock || static_cast<std::uint8_t>(data[1]) != 0x50)
    in.fail(1, "header", "not a C3D file (expected at least 512 bytes with key byte 0x50)");
  const std::size_t parameter_start = (std::max<std::size_t>(static_cast<std::uint8_t>(data[0]), 1) - 1) * kBlock;
  const int processor = in.u8(parameter_start + 3, "processor type");
  if (processor < 84 || processor > 86) in.fail(parameter_start + 3, "processor type", std::to_string(processor) + " (expected 84 Intel, 85 DEC or 86 MIPS)");
  in.processor = processor == 84 ? C3dFile::Processor::kIntel : processor == 85 ? C3dFile::Processor::kDec : C3dFile::Processor::kMips;
  f.processor = in.processor;
  f.parameters = read_parameters(in, parameter_start);

  // Header words; parameters win where both say (POINT:SCALE, POINT:RATE, ANALOG:RATE).
  const int points = in.u16(2, "header points");
  const int analog_per_frame = in.u16(4, "header analog measurements");
  f.first_frame = in.u16(6, "header first frame");
  int last_frame = in.u16(8, "header last frame");
  const double scale = number(f, "POINT", "SCALE", in.f32(12, "header scale"));
  const std::size_t data_start = (std::max<std::size_t>(in.u16(16, "header data block"), 1) - 1) * kBlock;
  const int samples = in.u16(18, "header analog samples per frame");
  const double rate = number(f, "POINT", "RATE", in.f32(20, "header frame rate"));
  // Files over 65,535 frames give the range in TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD (two 16-bit words each).
  if (const C3dParameter* s = f.parameter("TRIAL", "ACTUAL_START_FIELD"); s && s->numbers.size() == 2) {
    const C3dParameter* e = f.parameter("TRIAL", "ACTUAL_END_FIELD");
    if (e && e->numbers.size() == 2) {
      // Two unsigned 16-bit words, which files store as signed ones too (-1 is 65535); anything else
      // (a damaged file: found by fuzzing) is refused.
      auto word32 = [&](const C3dParameter& p) {
        long value = 0;
        for (std::size_t k = 0; k < 2; ++k) {
          const double w = p.numbers[k];
          if (!(w >= -32768 && w <= 65535) || w != std::floor(w))
            throw InputError(f.name, 0, "TRIAL:" + p.name, "expected two 16-bit words, got " + std::to_string(w));
          value += (static_cast<long>(w) + (w < 0 ? 65536L : 0L)) << (16 * k);
        }
        if (value > std::numeric_limits<int>::max())
          throw InputError(f.name, 0, "TRIAL:" + p.name, "frame " + std::to_string(value) + " is past what a file can hold");
        return value;
      };
      f.first_frame = static_cast<int>(word32(*s));
      last_frame = static_cast<int>(word32(*e));
    }
  }
  const int frames = last_frame >= f.first_frame ? last_frame - f.first_frame + 1 : 0;
  if (!(rate > 0 && std::isfinite(rate))) in.fail(20, "POINT:RATE", "frame rate " + std::to_string(rate) + " (expected a positive number)");
  if (!std::isfinite(scale) || scale == 0) in.fail(12, "POINT:SCALE", "scale " + std::to_string(scale) + " (expected a non-zero number)");
  f.floating_point = scale < 0;
  const std::size_t width = f.floating_point ? 4 : 2;
  const int channels = samples > 0 ? analog_per_frame / samples : 0;
  if (samples > 0 && analog_per_frame % samples != 0)
    in.fail(4, "header analog measurements", std::to_string(analog_per_frame) + " is not a multiple of the " + std::to_string(samples) + " samples per frame");
  const std::size_t frame_bytes = (4 * static_cast<std::size_t>(points) + static_cast<std::size_t>(analog_per_frame)) * width;
  in.need(data_start, frame_bytes * static_cast<std::size_t>(frames), "data (" + std::to_string(frames) + " frames)");

  // Points.
  MarkerTrial& m = f.markers;
  m.marker_names = labels(f, "POINT", "LABELS", points);
  for (int k = 0; k < points; ++k)
    if (m.marker_names[static_cast<std::size_t>(k)].empty()) m.marker_names[static_cast<std::size_t>(k)].append("M").append(std::to_string(k + 1));
  const C3dParameter* units = f.parameter("POINT", "UNITS");
  m.units_in_file = units && !units->strings.empty() && !text::trim(units->strings[0]).empty() ? std::string(text::trim(units->strings[0])) : "mm";
  double metres;
  try {
    metres = metres_per_unit(m.units_in_file);
  } catch (const std::invalid_argument& e) {
    throw InputError(name, 0, "POINT:UNITS", e.what());
  }
  m.data_rate_hz = m.camera_rate_hz = m.orig_data_rate_hz = rate;
  m.orig_data_start_frame = f.first_frame;
  m.orig_num_frames = frames;
  m.positions_m.resize(3, static_cast<Eigen::Index>(frames) * points);
  const double point_scale = f.floating_point ? 1.0 : std::abs(scale);
  auto value = [&](std::size_t at, const char* field) { return f.floating_point ? static_cast<double>(in.f32(at, field)) : in.i16(at, field); };
  f.analog.values.resize(static_cast<Eigen::Index>(frames) * samples, channels);
  for (int fr = 0; fr < frames; ++fr) {
    m.frame_numbers.push_back(f.first_frame + fr);
    m.time_s.push_back((f.first_frame - 1 + fr) / rate);
    const std::size_t base = data_start + static_cast<std::size_t>(fr) * frame_bytes;
    for (int p = 0; p < points; ++p) {
      const std::size_t at = base + static_cast<std::size_t>(p) * 4 * width;
      // The fourth word: camera mask (high byte) and residual (low byte); a negative word is a missing point.
      const double residual = value(at + 3 * width, "point residual");
      Eigen::Vector3d x(value(at, "point x"), value(at + width, "point y"), value(at + 2 * width, "point z"));
      if (residual < 0 || !x.allFinite()) x.setConstant(std::numeric_limits<double>::quiet_NaN());
      m.positions_m.col(static_cast<Eigen::Index>(fr) * points + p) = x * point_scale * metres;
    }
    const std::size_t analog_at = base + 4 * static_cast<std::size_t>(points) * width;
    for (int s = 0; s < samples; ++s)
      for (int c = 0; c < channels; ++c)
        f.analog.values(static_cast<Eigen::Index>(fr) * samples + s, c) =
            value(analog_at + (static_cast<std::size_t>(s) * channels + c) * width, "analog sample");
  }

  // Analog channels in their units.
  f.analog.samples_per_frame = samples;
  f.analog.rate_hz = number(f, "ANALOG", "RATE", rate * samples);
  f.analog.labels = labels(f, "ANALOG", "LABELS", channels);
  const C3dParameter* analog_units = f.parameter("ANALOG", "UNITS");
  for (int c = 0; c < channels; ++c)
    f.analog.units.push_back(analog_units && static_cast<int>(analog_units->strings.size()) > c ? analog_units->strings[static_cast<std::size_t>(c)] : "");
  const double gen_scale = number(f, "ANALOG", "GEN_SCALE", 1.0);
  const C3dParameter* format = f.parameter("ANALOG", "FORMAT");
  const bool unsigned_data = !f.floating_point && format && !format->strings.empty() && format->strings[0] == "UNSIGNED";
  for (int c = 0; c < channels; ++c) {
    double offset = number(f, "ANALOG", "OFFSET", 0.0, static_cast<std::size_t>(c));
    if (unsigned_data && offset < 0) offset += 65536;
    const double channel_scale = number(f, "ANALOG", "SCALE", 1.0, static_cast<std::size_t>(c));
    auto col = f.analog.values.col(c);
    if (unsigned_data) col = col.unaryExpr([](double v) { return v < 0 ? v + 65536 : v; });
    col = (col.array() - offset) * channel_scale * gen_scale;
  }
  read_events(f);
  return f;
}

C3dFile read_c3d(const std::string& path, const C3dReadOptions& options) {
  return parse_c3d(text::read_file(path, options.max_bytes), path);
}

}  // namespace cpgait
