#include "review_data.h"

#include <Eigen/Geometry>
#include <cmath>

#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/osim_reader.h"

namespace cpgait::services {
using nlohmann::json;

namespace {
double round6(double v) { return std::round(v * 1e6) / 1e6; }  // micrometres: enough to draw, half the bytes
}  // namespace

json trial_kinematics_json(const std::string& model_path, const std::string& marker_set_path, const std::string& ik_mot_path,
                           const std::string& markers_trc, const std::string& grf_mot, const std::string& loads_xml) {
  OsimReadOptions ro;
  ro.marker_set_file = marker_set_path;
  const Model model = read_osim(model_path, ro).model;
  const Storage ik = read_storage(ik_mot_path);
  const MarkerTrial trial = parse_marker_file(markers_trc, "markers");
  std::unique_ptr<AppliedLoads> loads;
  if (!grf_mot.empty()) loads = std::make_unique<AppliedLoads>(model, parse_external_loads(loads_xml, "loads.xml"), parse_storage(grf_mot, "grf.mot"));

  json bodies = json::array();
  for (std::size_t b = 1; b < model.bodies.size(); ++b)
    bodies.push_back({{"name", model.bodies[b].name},
                      {"parent", model.bodies[model.joints[model.bodies[b].joint].parent_body].name},
                      {"mass_kg", model.bodies[b].mass_kg}});
  json model_markers = json::array(), measured_names = json::array();
  for (const auto& m : model.markers) model_markers.push_back(m.name);
  for (const auto& n : trial.marker_names) measured_names.push_back(n);

  std::vector<int> columns(model.num_coordinates());
  for (int c = 0; c < model.num_coordinates(); ++c) columns[c] = ik.column(model.coordinates[c].name);
  const bool degrees = ik.in_degrees.value_or(true);
  KinematicsWorkspace<double> ws(model);
  std::vector<AppliedLoads::Sample> samples;
  json frames = json::array();
  int trial_frame = 0;
  for (int r = 0; r < ik.num_rows(); ++r) {
    const double t = ik.time()[r];
    Eigen::VectorXd q = model.default_coordinates();
    for (int c = 0; c < model.num_coordinates(); ++c)
      if (columns[c] >= 0) q[c] = ik.data(r, columns[c]) * (degrees && model.coordinates[c].is_angle() ? M_PI / 180.0 : 1.0);
    forward_kinematics(model, q.data(), ws);
    json poses = json::array(), coms = json::array(), mm = json::array(), measured = json::array(), forces = json::array();
    for (std::size_t b = 1; b < model.bodies.size(); ++b) {
      const auto& X = ws.body_in_ground[b];
      const Eigen::Quaterniond quat(X.rotation);
      const Eigen::Vector3d com = X.rotation * model.bodies[b].com_m + X.translation_m;
      poses.push_back({round6(X.translation_m.x()), round6(X.translation_m.y()), round6(X.translation_m.z()), round6(quat.x()),
                       round6(quat.y()), round6(quat.z()), round6(quat.w())});
      coms.push_back({round6(com.x()), round6(com.y()), round6(com.z())});
    }
    for (int k = 0; k < static_cast<int>(model.markers.size()); ++k) {
      const Eigen::Vector3d p = marker_position(model, k, ws);
      mm.push_back({round6(p.x()), round6(p.y()), round6(p.z())});
    }
    while (trial_frame + 1 < trial.num_frames() && std::abs(trial.time_s[trial_frame + 1] - t) < std::abs(trial.time_s[trial_frame] - t)) ++trial_frame;
    for (int k = 0; k < trial.num_markers(); ++k) {
      const auto p = trial.position_m(trial_frame, k);
      if (std::isnan(p[0])) measured.push_back(nullptr);
      else measured.push_back({round6(p.x()), round6(p.y()), round6(p.z())});
    }
    if (loads) {
      loads->forces_at(t, ws, samples);
      for (const auto& s : samples)
        forces.push_back({{"body", model.bodies[s.body].name},
                          {"point", {round6(s.point_m.x()), round6(s.point_m.y()), round6(s.point_m.z())}},
                          {"force", {round6(s.force_N.x()), round6(s.force_N.y()), round6(s.force_N.z())}}});
    }
    frames.push_back({{"time", t}, {"bodies", poses}, {"com", coms}, {"model_markers", mm}, {"measured_markers", measured}, {"grf", forces}});
  }
  return {{"units", {{"length", "m"}, {"force", "N"}, {"time", "s"}}},
          {"up", {model.gravity_m_s2.x() == 0 && model.gravity_m_s2.z() == 0 ? "y" : "custom"}},
          {"bodies", bodies},
          {"model_marker_names", model_markers},
          {"measured_marker_names", measured_names},
          {"frames", frames}};
}

}  // namespace cpgait::services
