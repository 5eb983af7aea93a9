#pragma once
// C3D force platforms (the C3D User Guide's FORCE_PLATFORM group): types 1 (F, COP, Tz), 2 (F, M),
// 3 (Kistler's eight channels) and 4 (type 2 through its CAL_MATRIX). Each plate's forces, centre of
// pressure and free moment in the lab frame as recorded, acting on the subject, in SI units.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "cpgait/capture/c3d.h"

namespace cpgait {

struct ForcePlate {
  int number = 0;  // 1-based, as the file counts them
  int type = 0;
  std::array<Eigen::Vector3d, 4> corners_m;  // lab frame
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  // the working surface's centre: the corners' mean
  // The plate's axes in the lab: x along corner 2 -> 1, z = x cross (corner 4 -> 1), y = z cross x.
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  // ORIGIN: from the transducer to the surface centre, plate frame (a positive z is flipped, as
  // vendors write it either way); type 3: the sensors' offsets a, b and az0.
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();
  std::vector<int> channels;  // 0-based analog columns: 6, or 8 for type 3
  Eigen::Matrix<double, 6, 6> calibration = Eigen::Matrix<double, 6, 6>::Identity();  // type 4
};

// Per analog sample, lab frame as recorded.
struct PlateForces {
  Eigen::Matrix3Xd force_N;         // on the subject
  Eigen::Matrix3Xd cop_m;           // on the surface; the centre where the force is below the threshold
  Eigen::Matrix3Xd free_moment_Nm;  // about the plate's normal through the COP, on the subject
  // The plate's channels gave the force on the plate rather than on the subject: negated.
  bool negated = false;
};

// The file's plates (FORCE_PLATFORM:USED of them). Throws InputError naming the file and the
// parameter (FORCE_PLATFORM:TYPE, CORNERS, ORIGIN, CHANNEL, CAL_MATRIX) when one is missing, short,
// names an analog channel the file lacks, or gives a type other than 1-4.
std::vector<ForcePlate> read_force_plates(const C3dFile& file);

// `up`: the lab's vertical (unit, in the file's frame), used to tell the force on the subject (upward
// while loaded) from the force on the plate, and to apply the threshold (N) on the vertical force
// below which the plate is unloaded (force and moment 0, COP the centre). lowpass_hz > 0: the force
// and moment are low-passed first (zero-phase 3rd-order Butterworth, as OpenSim filters), then the COP
// is computed from them.
PlateForces plate_forces(const C3dFile& file, const ForcePlate& plate, const Eigen::Vector3d& up, double threshold_N,
                         double lowpass_hz = 0);

// The lab's vertical axis (0 x, 1 y, 2 z), upward positive: the plates' normal when the file has
// plates, else POINT:Y_SCREEN's axis, else z.
int c3d_vertical_axis(const C3dFile& file);

}  // namespace cpgait
