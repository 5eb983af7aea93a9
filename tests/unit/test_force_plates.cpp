// C3D force plates: ezc3d's values for the Qualisys file; a plate of each type (1-4) written with a
// known wrench (one also as the force on the plate) and read back to its COP and free moment; the
// vendors' files converted to OpenSim's GRF and loads, their stances against the files' own events.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdio>

#include "c3d_writer.h"
#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/force_plates.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/marker_file.h"
#include "test_support.h"

using namespace cpgait;
using cpgait::testing::C3dWriter;

namespace {

std::string c3d_path(const std::string& file) { return refdata::shared_path("c3d/" + file); }

// The known load: on the subject, lab frame (Z up), on a 600 x 400 mm plate centred at (0.3, 0.2, 0).
const Eigen::Vector3d kForce(20, -30, 700), kCop(0.35, 0.15, 0), kFreeMoment(0, 0, 5);

// One plate of the given type, one marker (RHEE, above the COP), two frames at 100 Hz with one
// analog sample each: loaded, then unloaded. `on_plate`: the channels give the force on the plate.
std::string plate_c3d(int type, bool on_plate) {
  // Plate axes from the corners: x = c1 - c2 = lab +y, y = lab +x, z = lab -z.
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d::UnitY();
  R.col(1) = Eigen::Vector3d::UnitX();
  R.col(2) = -Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d centre(0.3, 0.2, 0);
  const double sign = on_plate ? -1.0 : 1.0;
  const Eigen::Vector3d F = sign * (R.transpose() * kForce), r = R.transpose() * (kCop - centre), T = sign * (R.transpose() * kFreeMoment);
  const Eigen::Vector3d Mc = r.cross(F) + T;  // about the surface centre, plate frame
  const Eigen::Vector3d origin_stored_mm(-1, 2, 40);  // a positive z, as some vendors write it: read as (1, -2, -40)
  const Eigen::Vector3d o = -origin_stored_mm / 1000.0;
  const Eigen::Vector3d kistler(0.12, 0.2, -0.045);  // type 3: a, b, az0
  Eigen::Matrix<double, 6, 6> cal = Eigen::Matrix<double, 6, 6>::Identity() * 2.0;
  cal(0, 1) = 0.1, cal(4, 2) = -0.3, cal(5, 0) = 0.05;
  std::vector<double> ch;
  std::vector<std::string> units;
  if (type == 1) {
    ch = {F.x(), F.y(), F.z(), 1000 * r.x(), 1000 * r.y(), 1000 * T.z()};
    units = {"N", "N", "N", "mm", "mm", "Nmm"};
  } else if (type == 2 || type == 4) {
    const Eigen::Vector3d Ms = Mc - F.cross(o);  // about the transducer
    Eigen::Matrix<double, 6, 1> raw;
    raw << F, 1000 * Ms;
    if (type == 4) {
      Eigen::Matrix<double, 6, 6> to_si = Eigen::Matrix<double, 6, 6>::Identity();
      to_si.bottomRightCorner<3, 3>() *= 1e-3;
      raw = to_si.inverse() * cal.inverse() * to_si * raw;  // the channels the matrix turns into F, M
    }
    ch.assign(raw.data(), raw.data() + 6);
    units = {"N", "N", "N", "Nmm", "Nmm", "Nmm"};
  } else {
    const double a = kistler.x(), b = kistler.y();
    const Eigen::Vector3d M = Mc - F.cross(Eigen::Vector3d(0, 0, kistler.z()));
    const double P = M.x() / b, Q = M.y() / a, D = M.z() / b;
    ch = {(F.x() - D) / 2, (F.x() + D) / 2, F.y() / 2, F.y() / 2, (F.z() + P - Q) / 4, (F.z() + P + Q) / 4, (F.z() - P + Q) / 4,
          (F.z() - P - Q) / 4};
    units.assign(8, "N");
  }
  const int channels = static_cast<int>(ch.size());
  C3dWriter w;
  w.u8(2), w.u8(0x50);
  w.i16(1), w.i16(channels), w.i16(1), w.i16(2), w.i16(0);
  w.f32(-1.0f);
  w.i16(6), w.i16(1);
  w.f32(100.0f);
  w.pad();
  w.u8(1), w.u8(0x50), w.u8(4), w.u8(84);
  w.group(1, "POINT");
  w.parameter(1, "USED", 2, {}, [&] { w.i16(1); });
  w.parameter(1, "SCALE", 4, {}, [&] { w.f32(-1.0f); });
  w.parameter(1, "RATE", 4, {}, [&] { w.f32(100.0f); });
  w.parameter(1, "UNITS", -1, {2}, [&] { w.out += "mm"; });
  w.parameter(1, "LABELS", -1, {4, 1}, [&] { w.out += "RHEE"; });
  w.group(2, "ANALOG");
  w.parameter(2, "USED", 2, {}, [&] { w.i16(channels); });
  w.parameter(2, "RATE", 4, {}, [&] { w.f32(100.0f); });
  w.parameter(2, "GEN_SCALE", 4, {}, [&] { w.f32(1.0f); });
  w.parameter(2, "SCALE", 4, {channels}, [&] { for (int c = 0; c < channels; ++c) w.f32(1.0f); });
  w.parameter(2, "OFFSET", 2, {channels}, [&] { for (int c = 0; c < channels; ++c) w.i16(0); });
  w.parameter(2, "UNITS", -1, {3, channels}, [&] { for (const auto& u : units) w.out += u + std::string(3 - u.size(), ' '); });
  w.group(3, "FORCE_PLATFORM");
  w.parameter(3, "USED", 2, {}, [&] { w.i16(1); });
  w.parameter(3, "TYPE", 2, {1}, [&] { w.i16(type); });
  w.parameter(3, "CORNERS", 4, {3, 4, 1}, [&] {
    for (float v : {600.f, 400.f, 0.f, 600.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 400.f, 0.f}) w.f32(v);
  });
  w.parameter(3, "ORIGIN", 4, {3, 1}, [&] {
    const Eigen::Vector3d v = type == 3 ? Eigen::Vector3d(1000 * kistler) : origin_stored_mm;
    for (int k = 0; k < 3; ++k) w.f32(static_cast<float>(v[k]));
  });
  w.parameter(3, "CHANNEL", 2, {channels, 1}, [&] { for (int c = 1; c <= channels; ++c) w.i16(c); });
  if (type == 4)
    w.parameter(3, "CAL_MATRIX", 4, {6, 6, 1}, [&] {
      for (int c = 0; c < 6; ++c)
        for (int r2 = 0; r2 < 6; ++r2) w.f32(static_cast<float>(cal(r2, c)));  // by column
    });
  w.u8(0), w.u8(0);
  w.out.resize(5 * 512, '\0');
  for (int f = 0; f < 2; ++f) {
    for (float v : {350.f, 150.f, 50.f, 1.f}) w.f32(v);
    for (double v : ch) w.f32(f == 0 ? static_cast<float>(v) : 0.0f);
  }
  w.pad();
  return w.out;
}

}  // namespace

TEST(ForcePlates, EachTypeGivesTheWrenchItWasWrittenWith) {
  for (int type = 1; type <= 4; ++type)
    for (bool on_plate : {false, true}) {
      if (on_plate && type != 2) continue;
      SCOPED_TRACE("type " + std::to_string(type) + (on_plate ? ", force on the plate" : ""));
      const C3dFile f = parse_c3d(plate_c3d(type, on_plate), "plates.c3d");
      const auto plates = read_force_plates(f);
      ASSERT_EQ(plates.size(), 1u);
      EXPECT_EQ(plates[0].type, type);
      EXPECT_TRUE(plates[0].centre_m.isApprox(Eigen::Vector3d(0.3, 0.2, 0)));
      EXPECT_EQ(c3d_vertical_axis(f), 2);
      const PlateForces pf = plate_forces(f, plates[0], Eigen::Vector3d::UnitZ(), 20.0);
      EXPECT_EQ(pf.negated, on_plate);
      EXPECT_LT((pf.force_N.col(0) - kForce).norm(), 1e-3) << pf.force_N.col(0).transpose();
      EXPECT_LT((pf.cop_m.col(0) - kCop).norm(), 1e-6) << pf.cop_m.col(0).transpose();
      EXPECT_LT((pf.free_moment_Nm.col(0) - kFreeMoment).norm(), 1e-3) << pf.free_moment_Nm.col(0).transpose();
      // Unloaded: nothing applied, the point at the plate's centre.
      EXPECT_EQ(pf.force_N.col(1).norm(), 0.0);
      EXPECT_TRUE(pf.cop_m.col(1).isApprox(Eigen::Vector3d(0.3, 0.2, 0)));
    }
}

// The GRF table and loads for that plate: one stance of the right foot (RHEE), in OpenSim's frame.
TEST(ForcePlates, GroundReactionsInOpenSimsFrameOnTheNearestFoot) {
  const C3dFile f = parse_c3d(plate_c3d(2, false), "plates.c3d");
  const Eigen::Matrix3d to_y_up = c3d_to_opensim(f, C3dVertical::kAuto);
  const GroundReactions g = ground_reactions(f, to_y_up, {20.0, {}, "calcn_r", "calcn_l", 0.0, 0.0});
  ASSERT_EQ(g.stances.size(), 1u);
  EXPECT_EQ(g.stances[0].foot, 'r');
  ASSERT_EQ(g.loads.size(), 1u);
  EXPECT_EQ(g.loads[0], (std::pair<std::string, std::string>{"1_", "calcn_r"}));
  const Storage& s = g.grf;
  EXPECT_NEAR(s.data(0, s.column("1_ground_force_vy")), 700, 1e-3);   // up
  EXPECT_NEAR(s.data(0, s.column("1_ground_force_vz")), 30, 1e-3);    // lab -y
  EXPECT_NEAR(s.data(0, s.column("1_ground_force_pz")), -0.15, 1e-6);
  EXPECT_NEAR(s.data(0, s.column("1_ground_torque_y")), 5, 1e-3);
  // The loads document names the columns and the body, and cpgait's reader takes it.
  const ExternalLoadsSpec spec = parse_external_loads(external_loads_document(g, "plates_grf.mot"), "plates_grf.xml");
  ASSERT_EQ(spec.forces.size(), 1u);
  EXPECT_EQ(spec.forces[0].applied_to_body, "calcn_r");
  EXPECT_EQ(spec.forces[0].force_identifier, "1_ground_force_v");
  EXPECT_EQ(spec.forces[0].torque_identifier, "1_ground_torque_");
  EXPECT_EQ(spec.datafile, "plates_grf.mot");
}

TEST(ForcePlates, DamagedPlateParametersNameTheParameter) {
  std::string bytes = plate_c3d(2, false);
  const auto at = bytes.find("CHANNEL");
  ASSERT_NE(at, std::string::npos);
  // The first channel number (after name, link, type, dims): 99 does not exist.
  const std::size_t value = at + 7 + 2 + 1 + 1 + 2;
  bytes[value] = 99, bytes[value + 1] = 0;
  const C3dFile f = parse_c3d(bytes, "bad.c3d");
  try {
    read_force_plates(f);
    FAIL() << "a channel past the file's was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "FORCE_PLATFORM:CHANNEL");
    EXPECT_NE(e.message().find("99"), std::string::npos) << e.what();
  }
}

// ezc3d's test values for the Qualisys file's first plate, first sample (no threshold): force (N),
// centre of pressure and free moment (its mm and N mm in SI) to 1e-12, and the second plate's corners
// and origin (floats in the file) to 1 um.
TEST(ForcePlatesReference, QualisysMatchesEzc3d) {
  REQUIRE_REFERENCE(c3d_path("Qualisys.c3d"));
  const C3dFile f = read_c3d(c3d_path("Qualisys.c3d"));
  const auto plates = read_force_plates(f);
  ASSERT_EQ(plates.size(), 2u);
  EXPECT_EQ(plates[0].type, 2);
  EXPECT_LT((plates[1].corners_m[0] - Eigen::Vector3d(1.017, 0.464, 0)).norm(), 1e-6) << plates[1].corners_m[0].transpose();
  EXPECT_LT((plates[1].corners_m[2] - Eigen::Vector3d(0.509, 0, 0)).norm(), 1e-6) << plates[1].corners_m[2].transpose();
  EXPECT_NEAR(plates[1].origin_m.x(), 1.016e-3, 1e-9);  // stored as floats (mm): ezc3d compares them as floats
  EXPECT_NEAR(plates[1].origin_m.z(), -36.322e-3, 1e-8);
  const PlateForces pf = plate_forces(f, plates[0], Eigen::Vector3d::UnitZ(), 0.0);
  EXPECT_FALSE(pf.negated);
  const Eigen::Vector3d force(0.13992118835449219, 0.046148300170898438, -0.18352508544921872);
  const Eigen::Vector3d cop(0.22881266090518048, 0.11829556977523387, 0.0);
  EXPECT_LT((pf.force_N.col(0) - force).norm(), 1e-12);
  EXPECT_LT((pf.cop_m.col(0) - cop).norm(), 1e-12);
  EXPECT_NEAR(pf.free_moment_Nm(2, 0), -44.140528790099872e-3, 1e-12);
}

// The vendors' files: what each holds, the lab's vertical, the stances and their feet against the
// file's own gait events (Qualisys), and the body weight the single stances carry.
TEST(ForcePlatesReference, VendorFilesGiveStancesTheirEventsAgreeWith) {
  for (const auto& file : {"Qualisys.c3d", "BTS.c3d", "Vicon.c3d"}) REQUIRE_REFERENCE(c3d_path(file));
  struct Expect {
    const char* file;
    int vertical, plates, stances;
  };
  for (const Expect& x : {Expect{"Vicon.c3d", 2, 0, 0}, Expect{"Qualisys.c3d", 2, 2, 2}, Expect{"BTS.c3d", 1, 6, 3}}) {
    SCOPED_TRACE(x.file);
    const C3dFile f = read_c3d(c3d_path(x.file));
    EXPECT_EQ(c3d_vertical_axis(f), x.vertical);
    EXPECT_EQ(static_cast<int>(read_force_plates(f).size()), x.plates);
    const GroundReactions g = ground_reactions(f, c3d_to_opensim(f, C3dVertical::kAuto));
    ASSERT_EQ(static_cast<int>(g.stances.size()), x.stances);
    if (x.stances == 0) continue;
    // Single stance: while the other foot is off the ground, from its toe off to its heel strike, as
    // the plates (the other foot's stances) or the file's events (xTO, xHS) tell.
    std::vector<std::pair<char, double>> off, on;  // foot, time
    for (const Stance& st : g.stances) off.emplace_back(st.foot, st.end_s), on.emplace_back(st.foot, st.begin_s);
    for (const C3dEvent& e : f.events) {
      const char foot = static_cast<char>(std::tolower(static_cast<unsigned char>(e.context.empty() ? e.label[0] : e.context[0])));
      if (e.label.find("TO") != std::string::npos || e.label.find("Off") != std::string::npos) off.emplace_back(foot, e.time_s);
      if (e.label.find("HS") != std::string::npos || e.label.find("Strike") != std::string::npos) on.emplace_back(foot, e.time_s);
    }
    std::vector<double> window_mean;
    for (std::size_t i = 0; i < g.stances.size(); ++i) {
      const Stance& st = g.stances[i];
      double t0 = 1e9, t1 = 1e9;
      for (const auto& [foot, t] : off)
        if (foot != st.foot && t > st.begin_s && t < st.end_s) t0 = std::min(t0, t);
      for (const auto& [foot, t] : on)
        if (foot != st.foot && t > t0 && t < st.end_s) t1 = std::min(t1, t);
      if (t1 > st.end_s) continue;
      const int vy = g.grf.column(std::to_string(st.plate) + "_ground_force_vy");
      double sum = 0;
      int count = 0;
      for (int k = 0; k < g.grf.num_rows(); ++k)
        if (g.grf.data(k, 0) >= t0 && g.grf.data(k, 0) <= t1) sum += g.grf.data(k, vy), ++count;
      window_mean.push_back(sum / count);
      std::printf("%s: plate %d (%c) single stance %.3f-%.3f s: mean vertical force %.1f N\n", x.file, st.plate, st.foot, t0, t1,
                  window_mean.back());
    }
    ASSERT_FALSE(window_mean.empty());
    double weight = 0;
    for (double m : window_mean) weight += m / static_cast<double>(window_mean.size());
    std::printf("%s: %d plates, %d stances; body weight from single stance %.0f N (a %.1f kg subject)\n", x.file, x.plates, x.stances,
                weight, weight / 9.80665);
    for (double m : window_mean) EXPECT_NEAR(m, weight, 0.05 * weight);
    EXPECT_GT(weight, 300.0);
    EXPECT_LT(weight, 1300.0);
  }
  // Qualisys: the left foot on plate 1 from its LHS to its LTO, the right on plate 2 from RHS to RTO.
  const C3dFile q = read_c3d(c3d_path("Qualisys.c3d"));
  ASSERT_EQ(q.events.size(), 7u);
  EXPECT_EQ(q.events[0].label, "LHS");
  EXPECT_NEAR(q.events[0].time_s, 3.59, 1e-6);
  const GroundReactions g = ground_reactions(q, c3d_to_opensim(q, C3dVertical::kAuto));
  const Stance &left = g.stances[0], &right = g.stances[1];
  EXPECT_EQ(left.plate, 1);
  EXPECT_EQ(left.foot, 'l');
  EXPECT_EQ(right.plate, 2);
  EXPECT_EQ(right.foot, 'r');
  EXPECT_NEAR(left.begin_s, 3.59, 0.02);   // LHS
  EXPECT_NEAR(left.end_s, 4.16, 0.03);     // LTO
  EXPECT_NEAR(right.begin_s, 4.05, 0.02);  // RHS
  EXPECT_NEAR(right.end_s, 4.65, 0.03);    // RTO
}

// Low-passed before the COP: the Qualisys plate's stance keeps its mean vertical force and loses its
// sample-to-sample noise.
TEST(ForcePlatesReference, LowPassKeepsTheStanceAndSmoothsIt) {
  REQUIRE_REFERENCE(c3d_path("Qualisys.c3d"));
  const C3dFile f = read_c3d(c3d_path("Qualisys.c3d"));
  const ForcePlate plate = read_force_plates(f).at(0);
  const PlateForces raw = plate_forces(f, plate, Eigen::Vector3d::UnitZ(), 20.0);
  const PlateForces smooth = plate_forces(f, plate, Eigen::Vector3d::UnitZ(), 20.0, 15.0);
  // Over the samples both call loaded (away from the edges, where the threshold cuts differently).
  double mean_raw = 0, mean_smooth = 0, rough_raw = 0, rough_smooth = 0;
  int n = 0;
  for (Eigen::Index s = 1; s + 1 < raw.force_N.cols(); ++s) {
    bool loaded = true;
    for (Eigen::Index k = s - 1; k <= s + 1; ++k) loaded = loaded && raw.force_N(2, k) > 0 && smooth.force_N(2, k) > 0;
    if (!loaded) continue;
    mean_raw += raw.force_N(2, s), mean_smooth += smooth.force_N(2, s);
    rough_raw += std::pow(raw.force_N(2, s - 1) - 2 * raw.force_N(2, s) + raw.force_N(2, s + 1), 2);
    rough_smooth += std::pow(smooth.force_N(2, s - 1) - 2 * smooth.force_N(2, s) + smooth.force_N(2, s + 1), 2);
    ++n;
  }
  ASSERT_GT(n, 500);
  std::printf("Qualisys plate 1, %d loaded samples: mean vertical force %.1f N raw, %.1f N low-passed at 15 Hz; second-difference RMS "
              "%.3f N -> %.5f N\n", n, mean_raw / n, mean_smooth / n, std::sqrt(rough_raw / n), std::sqrt(rough_smooth / n));
  EXPECT_NEAR(mean_smooth, mean_raw, 0.01 * mean_raw);
  EXPECT_LT(rough_smooth, rough_raw / 25.0);
}
