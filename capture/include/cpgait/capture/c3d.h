#pragma once
// C3D files (c3d.org's C3D User Guide): the header, the parameter section, 3-D points and analog
// channels, in the Intel, DEC and MIPS processor formats, integer or floating-point. Points come out
// as a MarkerTrial in metres in the file's own lab frame (a missing marker, residual < 0, is NaN);
// analog channels scaled to their units. Force plates and OpenSim's Y-up frame are built on this.
#include <Eigen/Core>
#include <string>
#include <string_view>
#include <vector>

#include "cpgait/capture/trc.h"

namespace cpgait {

struct C3dParameter {
  std::string group, name;
  int type = 0;                 // -1 characters, 1 bytes, 2 16-bit integers, 4 floats
  std::vector<int> dimensions;  // as stored: for characters the first is the string length
  std::vector<double> numbers;  // bytes, integers and floats, in storage order
  std::vector<std::string> strings;  // character data, one string per column, trailing blanks trimmed
};

struct C3dAnalog {
  std::vector<std::string> labels, units;
  double rate_hz = 0;
  int samples_per_frame = 0;  // analog samples per 3-D frame
  Eigen::MatrixXd values;     // samples x channels: (raw - OFFSET) * SCALE * GEN_SCALE
};

// EVENT group: a heel strike, toe off or other moment, on the points' clock ((frame - 1) / rate).
struct C3dEvent {
  std::string context;  // EVENT:CONTEXTS ("Left", "Right", ...), empty when the file has none
  std::string label;    // EVENT:LABELS ("Foot Strike", "LHS", ...)
  double time_s = 0;    // EVENT:TIMES: minutes * 60 + seconds
};

struct C3dFile {
  std::string name;
  enum class Processor { kIntel, kDec, kMips } processor = Processor::kIntel;
  bool floating_point = false;
  int first_frame = 1;  // the header's (1-based) first frame; TRC-style frame numbers follow it
  MarkerTrial markers;  // metres, lab frame as recorded; frame_numbers from first_frame, time (frame - 1) / rate
  C3dAnalog analog;
  std::vector<C3dParameter> parameters;
  std::vector<C3dEvent> events;  // in time order

  // GROUP:NAME, or null; names compare as stored (upper case by convention).
  const C3dParameter* parameter(std::string_view group, std::string_view name) const;
};

struct C3dReadOptions {
  std::size_t max_bytes = std::size_t{1} << 31;  // a larger file is refused before it is read
};

// Throws InputError naming the file, the byte offset or the parameter (GROUP:NAME) and what was expected.
C3dFile read_c3d(const std::string& path, const C3dReadOptions& options = {});
C3dFile parse_c3d(std::string_view bytes, const std::string& name);
// The header's key byte: a C3D file's second byte is 0x50.
bool looks_like_c3d(std::string_view bytes);

}  // namespace cpgait
