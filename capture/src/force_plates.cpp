#include "cpgait/capture/force_plates.h"

#include <cmath>

#include "cpgait/capture/input_error.h"
#include "cpgait/signal/lowpass.h"

namespace cpgait {
namespace {

const C3dParameter& required(const C3dFile& f, const char* name) {
  const C3dParameter* p = f.parameter("FORCE_PLATFORM", name);
  if (!p) throw InputError(f.name, 0, std::string("FORCE_PLATFORM:") + name, "missing, but the file says it has force plates");
  return *p;
}

// Metres per unit of a length ("mm", "cm", "m") or a moment ("Nmm", "N.mm", "Nm") unit.
double metres_per(std::string unit) {
  std::string u;
  for (char c : unit)
    if (c != ' ' && c != '.' && c != '*' && c != '-') u += c;
  if (u.size() >= 1 && (u[0] == 'N' || u[0] == 'n')) u = u.substr(1);
  if (u == "mm") return 1e-3;
  if (u == "cm") return 1e-2;
  return 1.0;  // m, or none
}

double point_unit_m(const C3dFile& f) {
  const C3dParameter* u = f.parameter("POINT", "UNITS");
  return u && !u->strings.empty() ? metres_per(u->strings[0]) : 1.0;
}

}  // namespace

std::vector<ForcePlate> read_force_plates(const C3dFile& f) {
  const C3dParameter* used = f.parameter("FORCE_PLATFORM", "USED");
  if (!used || used->numbers.empty() || used->numbers[0] < 1) return {};
  const int n = static_cast<int>(used->numbers[0]);
  const C3dParameter &type = required(f, "TYPE"), &corners = required(f, "CORNERS"), &origin = required(f, "ORIGIN"),
                     &channel = required(f, "CHANNEL");
  const double unit = point_unit_m(f);
  const int per_plate = channel.dimensions.empty() ? 6 : channel.dimensions[0];
  std::vector<ForcePlate> plates;
  for (int i = 0; i < n; ++i) {
    ForcePlate p;
    p.number = i + 1;
    const std::string which = "plate " + std::to_string(i + 1);
    if (static_cast<int>(type.numbers.size()) <= i) throw InputError(f.name, 0, "FORCE_PLATFORM:TYPE", "no type for " + which);
    p.type = static_cast<int>(type.numbers[static_cast<std::size_t>(i)]);
    if (p.type < 1 || p.type > 4)
      throw InputError(f.name, 0, "FORCE_PLATFORM:TYPE", which + " is of type " + std::to_string(p.type) + "; types 1-4 are read");
    if (corners.numbers.size() < static_cast<std::size_t>(12 * (i + 1)))
      throw InputError(f.name, 0, "FORCE_PLATFORM:CORNERS", "expected 12 numbers for " + which);
    for (int c = 0; c < 4; ++c)
      for (int k = 0; k < 3; ++k) p.corners_m[static_cast<std::size_t>(c)][k] = unit * corners.numbers[static_cast<std::size_t>(12 * i + 3 * c + k)];
    p.centre_m = (p.corners_m[0] + p.corners_m[1] + p.corners_m[2] + p.corners_m[3]) / 4.0;
    Eigen::Vector3d x = p.corners_m[0] - p.corners_m[1], y = p.corners_m[0] - p.corners_m[3];
    Eigen::Vector3d z = x.cross(y);
    if (!z.allFinite() || z.norm() < 1e-9 || x.norm() < 1e-6)
      throw InputError(f.name, 0, "FORCE_PLATFORM:CORNERS", which + "'s corners do not span a plane");
    y = z.cross(x);
    p.rotation.col(0) = x.normalized();
    p.rotation.col(1) = y.normalized();
    p.rotation.col(2) = z.normalized();
    if (origin.numbers.size() < static_cast<std::size_t>(3 * (i + 1)))
      throw InputError(f.name, 0, "FORCE_PLATFORM:ORIGIN", "expected 3 numbers for " + which);
    for (int k = 0; k < 3; ++k) p.origin_m[k] = unit * origin.numbers[static_cast<std::size_t>(3 * i + k)];
    if (p.type == 1) p.origin_m.head<2>().setZero();
    if (p.origin_m.z() > 0) p.origin_m = -p.origin_m;
    if (!p.origin_m.allFinite()) throw InputError(f.name, 0, "FORCE_PLATFORM:ORIGIN", which + "'s origin is not finite");
    const int needed = p.type == 3 ? 8 : 6;
    if (per_plate < needed || channel.numbers.size() < static_cast<std::size_t>(per_plate * (i + 1)))
      throw InputError(f.name, 0, "FORCE_PLATFORM:CHANNEL", "expected " + std::to_string(needed) + " channels for " + which);
    for (int c = 0; c < needed; ++c) {
      const double ch = channel.numbers[static_cast<std::size_t>(per_plate * i + c)];
      if (!(ch >= 1 && ch <= static_cast<double>(f.analog.values.cols())))
        throw InputError(f.name, 0, "FORCE_PLATFORM:CHANNEL",
                         which + " names analog channel " + std::to_string(static_cast<long long>(ch)) + "; the file has " +
                             std::to_string(f.analog.values.cols()));
      p.channels.push_back(static_cast<int>(ch) - 1);
    }
    if (p.type == 4) {
      const C3dParameter* cal = f.parameter("FORCE_PLATFORM", "CAL_MATRIX");
      if (cal && !cal->numbers.empty()) {
        if (cal->numbers.size() < static_cast<std::size_t>(36 * (i + 1)))
          throw InputError(f.name, 0, "FORCE_PLATFORM:CAL_MATRIX", "expected a 6 x 6 matrix for " + which);
        for (int r = 0; r < 6; ++r)
          for (int c = 0; c < 6; ++c) p.calibration(r, c) = cal->numbers[static_cast<std::size_t>(36 * i + 6 * c + r)];  // by column
        if (!p.calibration.allFinite()) throw InputError(f.name, 0, "FORCE_PLATFORM:CAL_MATRIX", which + "'s matrix is not finite");
      }
    }
    plates.push_back(p);
  }
  return plates;
}

PlateForces plate_forces(const C3dFile& f, const ForcePlate& p, const Eigen::Vector3d& up, double threshold_N, double lowpass_hz) {
  const Eigen::Index n = f.analog.values.rows();
  auto scale_of = [&](int channel, bool length) {
    const std::string u = static_cast<std::size_t>(channel) < f.analog.units.size() ? f.analog.units[static_cast<std::size_t>(channel)] : "";
    if (length) return u.empty() ? point_unit_m(f) : metres_per(u);
    return metres_per(u);  // moments: N mm -> N m
  };
  std::vector<double> scale(p.channels.size(), 1.0);
  if (p.type == 1) {
    scale[3] = scale_of(p.channels[3], true);
    scale[4] = scale_of(p.channels[4], true);
    scale[5] = scale_of(p.channels[5], false);
  } else if (p.type != 3) {
    for (int k = 3; k < 6; ++k) scale[static_cast<std::size_t>(k)] = scale_of(p.channels[static_cast<std::size_t>(k)], false);
  }
  // The wrench on the plate's axes about its surface centre, then in the lab.
  Eigen::Matrix3Xd F(3, n), M(3, n);
  for (Eigen::Index s = 0; s < n; ++s) {
    double ch[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (std::size_t c = 0; c < p.channels.size(); ++c) ch[c] = scale[c] * f.analog.values(s, p.channels[c]);
    Eigen::Vector3d force, moment;
    if (p.type == 1) {
      force << ch[0], ch[1], ch[2];
      moment = Eigen::Vector3d(ch[3], ch[4], 0).cross(force) + Eigen::Vector3d(0, 0, ch[5]);
    } else if (p.type == 3) {
      const double a = p.origin_m.x(), b = p.origin_m.y();
      force << ch[0] + ch[1], ch[2] + ch[3], ch[4] + ch[5] + ch[6] + ch[7];
      moment << b * (ch[4] + ch[5] - ch[6] - ch[7]), a * (ch[5] + ch[6] - ch[4] - ch[7]), b * (ch[1] - ch[0]) + a * (ch[2] - ch[3]);
      moment += force.cross(Eigen::Vector3d(0, 0, p.origin_m.z()));
    } else {
      Eigen::Matrix<double, 6, 1> raw;
      raw << ch[0], ch[1], ch[2], ch[3], ch[4], ch[5];
      if (p.type == 4) raw = p.calibration * raw;
      force = raw.head<3>();
      moment = raw.tail<3>() + force.cross(p.origin_m);  // from the transducer to the surface centre
    }
    F.col(s) = p.rotation * force;
    M.col(s) = p.rotation * moment;
  }
  if (lowpass_hz > 0 && n > 6 && f.analog.rate_hz > 0)
    for (int k = 0; k < 3; ++k) {
      F.row(k) = lowpass_butterworth3_zero_phase(F.row(k).transpose(), 1.0 / f.analog.rate_hz, lowpass_hz).transpose();
      M.row(k) = lowpass_butterworth3_zero_phase(M.row(k).transpose(), 1.0 / f.analog.rate_hz, lowpass_hz).transpose();
    }
  PlateForces out;
  // While loaded, the force on the subject points up; some vendors store the force on the plate.
  double vertical_sum = 0;
  for (Eigen::Index s = 0; s < n; ++s)
    if (std::abs(F.col(s).dot(up)) > threshold_N) vertical_sum += F.col(s).dot(up);
  if (vertical_sum < 0) {
    F = -F;
    M = -M;
    out.negated = true;
  }
  out.force_N.resize(3, n);
  out.cop_m.resize(3, n);
  out.free_moment_Nm.resize(3, n);
  for (Eigen::Index s = 0; s < n; ++s) {
    const Eigen::Vector3d fp = p.rotation.transpose() * F.col(s), mp = p.rotation.transpose() * M.col(s);
    if (!(std::abs(F.col(s).dot(up)) > threshold_N) || !fp.allFinite() || !mp.allFinite()) {
      out.force_N.col(s).setZero();
      out.free_moment_Nm.col(s).setZero();
      out.cop_m.col(s) = p.centre_m;
      continue;
    }
    // On the surface (plate z = 0): M = r x F + T with T along the normal.
    const Eigen::Vector3d r(-mp.y() / fp.z(), mp.x() / fp.z(), 0.0);
    const Eigen::Vector3d t = mp - r.cross(fp);
    out.force_N.col(s) = F.col(s);
    out.cop_m.col(s) = p.rotation * r + p.centre_m;
    out.free_moment_Nm.col(s) = p.rotation * Eigen::Vector3d(0, 0, t.z());
  }
  return out;
}

int c3d_vertical_axis(const C3dFile& f) {
  try {
    const std::vector<ForcePlate> plates = read_force_plates(f);
    if (!plates.empty()) {
      Eigen::Index axis = 2;
      plates[0].rotation.col(2).cwiseAbs().maxCoeff(&axis);
      return static_cast<int>(axis);
    }
  } catch (const InputError&) {
    // A damaged plate section says nothing about the lab's axes: fall through.
  }
  if (const C3dParameter* y = f.parameter("POINT", "Y_SCREEN"); y && !y->strings.empty() && !y->strings[0].empty()) {
    const char a = y->strings[0].back();
    if (a == 'X' || a == 'x') return 0;
    if (a == 'Y' || a == 'y') return 1;
  }
  return 2;
}

}  // namespace cpgait
