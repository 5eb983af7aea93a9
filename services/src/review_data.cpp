#include "review_data.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>

#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/gait_events.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_path.h"

namespace cpgait::services {
using nlohmann::json;

namespace {
double round6(double v) { return std::round(v * 1e6) / 1e6; }  // micrometres: enough to draw, half the bytes
double round4(double v) { return std::round(v * 1e4) / 1e4; }  // 0.1 mm: muscles are drawn 10 mm thick

// A treadmill: the belt's velocity as the simulations estimate it (the stance foot's), or null
// overground and for models without feet they know.
json treadmill_json(const Model& model, const std::vector<double>& time_s, const Eigen::MatrixXd& q_rows) {
  ContactSet feet = default_foot_contacts(model);
  if (feet.spheres.empty()) return nullptr;
  place_ground_under_feet(model, feet, time_s, q_rows);
  const Eigen::Vector3d& v = feet.ground_velocity_m_s;
  if (v.norm() == 0) return nullptr;
  return {{"belt_velocity_m_s", {round6(v.x()), round6(v.y()), round6(v.z())}}, {"height_m", round6(feet.ground_height_m)}};
}
}  // namespace

json trial_kinematics_json(const std::string& model_path, const std::string& marker_set_path, const std::string& ik_mot_path,
                           const std::string& markers_trc, const std::string& grf_mot, const std::string& loads_xml) {
  return trial_kinematics_json(model_path, marker_set_path, read_storage(ik_mot_path), markers_trc, grf_mot, loads_xml);
}

Storage motion_at_times(const Storage& motion, const std::vector<double>& times_s, double offset_s) {
  std::vector<double> kept;
  std::vector<int> rows;
  const auto t = motion.time();
  for (const double time : times_s) {
    const double local = time - offset_s;
    if (motion.num_rows() == 0 || local < t[0] - 1e-9 || local > t[motion.num_rows() - 1] + 1e-9) continue;
    // The nearest row: the first at or after `local`, or the one before it.
    const int after = static_cast<int>(std::lower_bound(t.begin(), t.end(), local) - t.begin());
    int best = std::min(after, motion.num_rows() - 1);
    if (after > 0 && (after == motion.num_rows() || local - t[after - 1] <= t[after] - local)) best = after - 1;
    kept.push_back(time);
    rows.push_back(best);
  }
  Storage out = motion;
  out.data.resize(static_cast<Eigen::Index>(rows.size()), motion.num_columns());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    out.data.row(static_cast<Eigen::Index>(i)) = motion.data.row(rows[i]);
    out.data(static_cast<Eigen::Index>(i), 0) = kept[i];
  }
  return out;
}

json trial_kinematics_json(const std::string& model_path, const std::string& marker_set_path, const Storage& ik,
                           const std::string& markers_trc, const std::string& grf_mot, const std::string& loads_xml) {
  OsimReadOptions ro;
  ro.marker_set_file = marker_set_path;
  const Model model = read_osim(model_path, ro).model;
  const MarkerTrial trial = parse_marker_file(markers_trc, "markers");
  std::unique_ptr<AppliedLoads> loads;
  if (!grf_mot.empty()) loads = std::make_unique<AppliedLoads>(model, parse_external_loads(loads_xml, "loads.xml"), parse_storage(grf_mot, "grf.mot"));

  json bodies = json::array();
  for (std::size_t b = 1; b < model.bodies.size(); ++b) {
    json meshes = json::array();
    for (const BodyMesh& mesh : model.bodies[b].meshes) {
      const Eigen::Quaterniond quat(mesh.pose.rotation);
      meshes.push_back({{"file", mesh.file}, {"scale", {mesh.scale.x(), mesh.scale.y(), mesh.scale.z()}},
                        {"translation", {mesh.pose.translation_m.x(), mesh.pose.translation_m.y(), mesh.pose.translation_m.z()}},
                        {"rotation", {quat.x(), quat.y(), quat.z(), quat.w()}}});
    }
    bodies.push_back({{"name", model.bodies[b].name},
                      {"parent", model.bodies[model.joints[model.bodies[b].joint].parent_body].name},
                      {"mass_kg", model.bodies[b].mass_kg},
                      {"meshes", meshes}});
  }
  json model_markers = json::array(), measured_names = json::array();
  for (const auto& m : model.markers) model_markers.push_back(m.name);
  for (const auto& n : trial.marker_names) measured_names.push_back(n);

  std::vector<int> columns(model.num_coordinates());
  for (int c = 0; c < model.num_coordinates(); ++c) columns[c] = ik.column(model.coordinates[c].name);
  const bool degrees = ik.in_degrees.value_or(true);
  KinematicsWorkspace<double> ws(model);
  std::vector<AppliedLoads::Sample> samples;
  std::vector<PathVertex<double>> path;
  json muscle_names = json::array();
  for (const auto& m : model.muscles) muscle_names.push_back(m.name);
  Eigen::MatrixXd q_rows(ik.num_rows(), model.num_coordinates());
  for (int r = 0; r < ik.num_rows(); ++r) {
    q_rows.row(r) = model.default_coordinates().transpose();
    for (int c = 0; c < model.num_coordinates(); ++c)
      if (columns[c] >= 0) q_rows(r, c) = ik.data(r, columns[c]) * (degrees && model.coordinates[c].is_angle() ? M_PI / 180.0 : 1.0);
  }
  const json treadmill = treadmill_json(model, std::vector<double>(ik.time().data(), ik.time().data() + ik.num_rows()), q_rows);
  json frames = json::array();
  int trial_frame = 0;
  for (int r = 0; r < ik.num_rows(); ++r) {
    const double t = ik.time()[r];
    const Eigen::VectorXd q = q_rows.row(r).transpose();
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
    // Each muscle's path in ground: its points, wrap tangent points included (flattened x y z).
    json muscle_paths = json::array();
    for (const auto& muscle : model.muscles) {
      current_path(model, muscle, q.data(), ws, path);
      std::vector<double> points;
      for (const auto& v : path) points.insert(points.end(), {round4(v.x_ground.x()), round4(v.x_ground.y()), round4(v.x_ground.z())});
      muscle_paths.push_back(points);
    }
    frames.push_back({{"time", t}, {"bodies", poses}, {"com", coms}, {"model_markers", mm}, {"measured_markers", measured}, {"grf", forces},
                      {"muscles", muscle_paths}});
  }
  return {{"units", {{"length", "m"}, {"force", "N"}, {"time", "s"}}},
          {"up", {model.gravity_m_s2.x() == 0 && model.gravity_m_s2.z() == 0 ? "y" : "custom"}},
          {"bodies", bodies},
          {"model_marker_names", model_markers},
          {"measured_marker_names", measured_names},
          {"muscle_names", muscle_names},
          {"treadmill", treadmill},
          {"frames", frames}};
}

}  // namespace cpgait::services

namespace cpgait::services {

namespace {

// 'r', 'l', or 0 for a column of neither side ("hip_flexion_l_moment" -> 'l').
char column_side(const std::string& column) {
  const std::string name = column_quantity(column);
  if (name.size() > 2 && name[name.size() - 2] == '_' && (name.back() == 'r' || name.back() == 'l')) return name.back();
  return 0;
}

// Each column's strides between one side's heel strikes (samples per stride, 0-100 % inclusive), their
// mean and SD; the side from the column's name (right for neither). Activations keep the model's muscles.
json cycle_series(const Model& model, const std::set<std::string>& muscles, const Storage& s, const std::map<char, std::vector<double>>& side_strikes,
                  const std::string& panel, int samples) {
  std::vector<double> time(s.time().data(), s.time().data() + s.num_rows());
  json series = json::array();
  for (int c = 1; c < s.num_columns(); ++c) {
    const std::string& name = s.labels[static_cast<std::size_t>(c)];
    if (panel == "activations" && !muscles.count(name)) continue;  // reserves and residuals
    const char side = column_side(name) ? column_side(name) : 'r';
    const auto found = side_strikes.find(side);
    if (found == side_strikes.end()) continue;
    const auto curves = cycle_curves(time, s.data.col(c), found->second, samples, true);
    if (curves.empty()) continue;
    json strides = json::array();
    Eigen::VectorXd mean = Eigen::VectorXd::Zero(samples), sq = Eigen::VectorXd::Zero(samples);
    for (const auto& curve : curves) {
      strides.push_back(std::vector<double>(curve.data(), curve.data() + samples));
      mean += curve.col(0);
    }
    mean /= static_cast<double>(curves.size());
    for (const auto& curve : curves) sq += (curve.col(0) - mean).array().square().matrix();
    const Eigen::VectorXd sd = curves.size() > 1 ? Eigen::VectorXd((sq / static_cast<double>(curves.size() - 1)).array().sqrt()) : Eigen::VectorXd(sq * 0.0);
    const bool moments = panel == "moments", activations = panel == "activations";
    const int ci = model.coordinate_index(moments ? name.substr(0, name.rfind('_')) : name);
    const bool linear = ci >= 0 && !model.coordinates[static_cast<std::size_t>(ci)].is_angle();
    const char* unit = activations ? "" : moments ? (linear ? "N" : "N·m") : (linear ? "m" : "deg");
    series.push_back({{"name", name}, {"side", side == 'l' ? "l" : "r"}, {"unit", unit}, {"strides", strides},
                      {"mean", std::vector<double>(mean.data(), mean.data() + samples)},
                      {"sd", std::vector<double>(sd.data(), sd.data() + samples)}});
  }
  return series;
}

// The reproduced gait's coordinates between its own heel strikes (simulated time), and those of its
// walks at other speed knobs: panels "gait" and "gait_speed_<knob>", when the gait stage ran.
void append_gait_cycle_panels(json& panels, const Model& model, const std::set<std::string>& muscles, const std::string& results_dir,
                              const std::string& trial_name, int samples) {
  const std::string base = results_dir + "/" + trial_name;
  if (!std::filesystem::exists(base + "_gait.json") || !std::filesystem::exists(base + "_gait.mot")) return;
  const json summary = json::parse(text::read_file(base + "_gait.json"));
  auto gait_strikes = [](const json& run) {
    std::map<char, std::vector<double>> out;
    out['r'] = run.at("heel_strikes_s").at("right").get<std::vector<double>>();
    out['l'] = run.at("heel_strikes_s").at("left").get<std::vector<double>>();
    return out;
  };
  panels.push_back({{"name", "gait"}, {"file", trial_name + "_gait.mot"}, {"speed_knob", 1.0},
                    {"series", cycle_series(model, muscles, read_storage(base + "_gait.mot"), gait_strikes(summary), "gait", samples)}});
  for (const json& run : summary.value("speed_knobs", json::array())) {
    const std::string file = results_dir + "/" + run.at("file").get<std::string>();
    if (!std::filesystem::exists(file)) continue;
    panels.push_back({{"name", "gait_speed_" + run.at("speed_knob").dump()},
                      {"file", run.at("file")}, {"speed_knob", run.at("speed_knob")},
                      {"series", cycle_series(model, muscles, read_storage(file), gait_strikes(run), "gait", samples)}});
  }
}

}  // namespace

std::string column_quantity(std::string column) {
  for (const char* suffix : {"_moment", "_force"})
    if (column.size() > std::strlen(suffix) && column.compare(column.size() - std::strlen(suffix), std::string::npos, suffix) == 0)
      column.resize(column.size() - std::strlen(suffix));
  return column;
}

json trial_cycles_json(const std::string& model_path, const std::string& marker_set_path, const std::string& results_dir,
                       const std::string& trial_name, const std::string& grf_mot, const std::string& loads_xml) {
  OsimReadOptions ro;
  ro.marker_set_file = marker_set_path;
  const Model model = read_osim(model_path, ro).model;
  const std::string base = results_dir + "/" + trial_name;
  const Storage ik = read_storage(base + "_ik.mot");
  std::vector<double> ik_time(ik.time().data(), ik.time().data() + ik.num_rows());

  // Heel strikes of each foot.
  std::map<char, std::vector<double>> strikes;
  std::map<char, std::string> source;
  if (!grf_mot.empty()) {
    const Storage grf = parse_storage(grf_mot, "grf.mot");
    for (const auto& f : parse_external_loads(loads_xml, "loads.xml").forces) {
      const char side = column_side(f.applied_to_body);
      const int col = grf.column(f.force_identifier + "y");
      if (!side || col < 0 || strikes[side].size() >= 2) continue;
      strikes[side] = contact_onsets(grf.time(), grf.data.col(col));
      source[side] = "GRF " + f.force_identifier + "y (20 N threshold)";
    }
  }
  for (const char side : {'r', 'l'}) {
    if (strikes[side].size() >= 2) continue;
    Eigen::MatrixXd q(ik.num_rows(), model.num_coordinates());
    for (int c = 0; c < model.num_coordinates(); ++c) {
      const int col = ik.column(model.coordinates[c].name);
      const double scale = ik.in_degrees.value_or(true) && model.coordinates[c].is_angle() ? M_PI / 180.0 : 1.0;
      q.col(c) = col >= 0 ? Eigen::VectorXd(ik.data.col(col) * scale) : Eigen::VectorXd::Constant(ik.num_rows(), model.default_coordinates()[c]);
    }
    const std::string foot = model.body_index(std::string("calcn_") + side) >= 0 ? std::string("calcn_") + side : std::string("foot_") + side;
    if (model.body_index(foot) < 0) continue;
    strikes[side] = heel_strikes_zeni(model, ik_time, q, foot);
    source[side] = "kinematics (Zeni 2008), " + foot;
  }

  constexpr int kSamples = 101;
  json percent = json::array();
  for (int k = 0; k < kSamples; ++k) percent.push_back(k);
  std::set<std::string> muscles;
  for (const auto& m : model.muscles) muscles.insert(m.name);
  struct Panel {
    const char *name, *suffix;
  };
  json panels = json::array();
  for (const Panel& p : {Panel{"kinematics", "_ik.mot"}, Panel{"moments", "_id.sto"}, Panel{"activations", "_StaticOptimization_activation.sto"}}) {
    const std::string file = base + p.suffix;
    if (!std::filesystem::exists(file)) continue;
    panels.push_back({{"name", p.name}, {"file", trial_name + p.suffix}, {"series", cycle_series(model, muscles, read_storage(file), strikes, p.name, kSamples)}});
  }
  append_gait_cycle_panels(panels, model, muscles, results_dir, trial_name, kSamples);
  json hs = json::object(), src = json::object();
  for (const char side : {'r', 'l'}) {
    hs[std::string(1, side)] = strikes[side];
    if (source.count(side)) src[std::string(1, side)] = source[side];
  }
  return {{"percent", percent}, {"heel_strikes_s", hs}, {"heel_strike_source", src}, {"panels", panels}};
}

}  // namespace cpgait::services
