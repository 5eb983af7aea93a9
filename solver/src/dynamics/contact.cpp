#include "cpgait/dynamics/contact.h"

#include <algorithm>
#include <stdexcept>

#include "cpgait/kinematics/forward_kinematics.h"

#include <cmath>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait {

double ground_height_at(const ContactSet& set, double x_m, double t_s) {
  if (set.step_height_m == 0) return set.ground_height_m;
  const double edge = set.step_x_m + set.ground_velocity_m_s.x() * t_s;
  return set.ground_height_m + set.step_height_m * 0.5 * (1 + std::tanh((x_m - edge) / set.step_edge_m));
}

Eigen::Vector3d sphere_contact_force(const ContactSphere& s, const ContactSet& set, const Eigen::Vector3d& c,
                                     const Eigen::Vector3d& v, double t_s) {
  const double d = s.radius_m - (c.y() - ground_height_at(set, c.x(), t_s));
  const double eps = set.smoothing_m;
  const double d_pos = 0.5 * (d + std::sqrt(d * d + eps * eps));
  const double rate = -v.y();  // penetration rate
  double fn = s.stiffness * std::pow(d_pos, 1.5) * (1 + 1.5 * s.dissipation * rate);
  fn = 0.5 * (fn + std::sqrt(fn * fn + 1e-12));  // smooth clamp at zero (no pulling)
  Eigen::Vector3d f(0, fn, 0);
  const Eigen::Vector3d v_rel = v - set.ground_velocity_m_s;
  const Eigen::Vector2d vt(v_rel.x(), v_rel.z());
  const double speed = std::sqrt(vt.squaredNorm() + 1e-12);
  const double x = speed / s.transition_velocity;
  // OpenSim's smooth Stribeck curve: rises to mu_s near the transition velocity, settles at mu_d,
  // plus a viscous part.
  const double mu = s.dynamic_friction * std::tanh(4 * x) + (s.static_friction - s.dynamic_friction) * x / std::pow(0.25 * x * x + 0.75, 2) +
                    s.viscous_friction * speed;
  f.x() = -mu * fn * v_rel.x() / speed;
  f.z() = -mu * fn * v_rel.z() / speed;
  return f;
}

namespace {

void read_sphere_fields(const nlohmann::json& j, ContactSphere& s, const std::string& name, const std::string& at) {
  auto num = [&](const char* key, double& out, double lo, double hi) {
    if (!j.contains(key)) return;
    out = json_field<double>(j, key, name, at);
    if (!(out >= lo && out <= hi))
      throw InputError(name, 0, (at.empty() ? std::string() : at + ".") + key, "expected " + std::to_string(lo) + " to " + std::to_string(hi));
  };
  num("radius_m", s.radius_m, 1e-3, 1.0);
  num("stiffness", s.stiffness, 1.0, 1e12);
  num("dissipation", s.dissipation, 0.0, 100.0);
  num("static_friction", s.static_friction, 0.0, 10.0);
  num("dynamic_friction", s.dynamic_friction, 0.0, 10.0);
  num("viscous_friction", s.viscous_friction, 0.0, 100.0);
  num("transition_velocity", s.transition_velocity, 1e-4, 10.0);
}

}  // namespace

ContactSet parse_contact_set_json(const std::string& text, const std::string& name, const Model& model) {
  const nlohmann::json j = parse_json_input(text, name);
  if (!j.is_object() || !j.contains("spheres") || !j["spheres"].is_array() || j["spheres"].empty())
    throw InputError(name, 0, "spheres", "expected an object with a non-empty \"spheres\" array");
  ContactSet set;
  if (j.contains("ground_height_m")) set.ground_height_m = json_field<double>(j, "ground_height_m", name, "");
  if (j.contains("ground_velocity_m_s")) {
    const auto v = json_field<std::vector<double>>(j, "ground_velocity_m_s", name, "");
    if (v.size() != 3) throw InputError(name, 0, "ground_velocity_m_s", "expected 3 numbers (m/s, ground frame)");
    set.ground_velocity_m_s = {v[0], v[1], v[2]};
  }
  if (j.contains("step_height_m")) set.step_height_m = json_field<double>(j, "step_height_m", name, "");
  if (j.contains("step_x_m")) set.step_x_m = json_field<double>(j, "step_x_m", name, "");
  if (j.contains("step_edge_m")) {
    set.step_edge_m = json_field<double>(j, "step_edge_m", name, "");
    if (!(set.step_edge_m > 0 && set.step_edge_m < 1)) throw InputError(name, 0, "step_edge_m", "expected 0 to 1 m");
  }
  ContactSphere defaults;
  if (j.contains("defaults")) {
    if (!j["defaults"].is_object()) throw InputError(name, 0, "defaults", "expected an object of sphere fields");
    read_sphere_fields(j["defaults"], defaults, name, "defaults");
  }
  for (std::size_t i = 0; i < j["spheres"].size(); ++i) {
    const auto& e = j["spheres"][i];
    const std::string at = "spheres[" + std::to_string(i) + "]";
    if (!e.is_object()) throw InputError(name, 0, at, "expected an object with \"body\" and \"location_m\"");
    ContactSphere s = defaults;
    s.name = json_field_or(e, "name", at, name, at);
    const std::string body = json_field<std::string>(e, "body", name, at);
    s.body = model.body_index(body);
    if (s.body <= 0) throw InputError(name, 0, at + ".body", "model " + model.name + " has no body " + body);
    const auto p = json_field<std::vector<double>>(e, "location_m", name, at);
    if (p.size() != 3) throw InputError(name, 0, at + ".location_m", "expected 3 numbers (m, body frame)");
    s.location_m = {p[0], p[1], p[2]};
    read_sphere_fields(e, s, name, at);
    set.spheres.push_back(s);
  }
  return set;
}

ContactSet read_contact_set(const std::string& path, const Model& model) {
  return parse_contact_set_json(text::read_file(path), path, model);
}

Eigen::Vector3d sphere_centre_m(const KinematicsWorkspace<double>& kin, const ContactSphere& s) {
  const auto& B = kin.body_in_ground[static_cast<std::size_t>(s.body)];
  return B.rotation * s.location_m + B.translation_m;
}

std::vector<Eigen::Vector3d> sphere_centres_over_poses(const Model& model, const ContactSet& set, const Eigen::MatrixXd& q) {
  KinematicsWorkspace<double> kws(model);
  const std::size_t ns = set.spheres.size();
  std::vector<Eigen::Vector3d> centre(static_cast<std::size_t>(q.rows()) * ns);
  for (int i = 0; i < q.rows(); ++i) {
    const Eigen::VectorXd qi = q.row(i).transpose();
    forward_kinematics(model, qi.data(), kws);
    for (std::size_t s = 0; s < ns; ++s) centre[static_cast<std::size_t>(i) * ns + s] = sphere_centre_m(kws, set.spheres[s]);
  }
  return centre;
}

void place_ground_under_feet(const Model& model, ContactSet& set, const std::vector<double>& t, const Eigen::MatrixXd& q) {
  if (set.spheres.empty() || q.rows() == 0) return;
  const std::size_t ns = set.spheres.size();
  const std::vector<Eigen::Vector3d> centre = sphere_centres_over_poses(model, set, q);
  std::vector<int> lowest(q.rows());
  double bottom = 1e30;
  for (int i = 0; i < q.rows(); ++i) {
    double low = 1e30;
    for (std::size_t s = 0; s < ns; ++s) {
      const double b = centre[i * ns + s].y() - set.spheres[s].radius_m;
      if (b < low) {
        low = b;
        lowest[i] = static_cast<int>(s);
      }
    }
    bottom = std::min(bottom, low);
  }
  // (The median of each pose's lowest bottom, nearer a standing foot's height, pressed subject01's
  // feet ~7 mm deeper and made CMC's integration fail at the first stance: measured.)
  const double weight_N = model.total_mass_kg() * model.gravity_m_s2.norm();
  set.ground_height_m = bottom + std::pow(0.5 * weight_N / set.spheres.front().stiffness, 2.0 / 3.0);

  std::vector<double> vx, vz;
  for (int i = 1; i + 1 < q.rows(); ++i) {
    const int s = lowest[i];
    if (centre[i * ns + s].y() - set.spheres[s].radius_m > set.ground_height_m + 0.01) continue;
    const Eigen::Vector3d v = (centre[(i + 1) * ns + s] - centre[(i - 1) * ns + s]) / (t[i + 1] - t[i - 1]);
    vx.push_back(v.x());
    vz.push_back(v.z());
  }
  set.ground_velocity_m_s.setZero();
  if (vx.empty()) return;
  auto median = [](std::vector<double> a) {
    std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
    return a[a.size() / 2];
  };
  const Eigen::Vector3d v(median(vx), 0.0, median(vz));
  if (v.norm() >= 0.1) set.ground_velocity_m_s = v;
}

ContactSet default_foot_contacts(const Model& model, int spheres_per_foot) {
  if (spheres_per_foot != 2 && spheres_per_foot != 5)
    throw std::invalid_argument("default_foot_contacts: 2 or 5 spheres per foot, not " + std::to_string(spheres_per_foot));
  const bool five = spheres_per_foot == 5;
  ContactSet set;
  std::vector<std::size_t> first_of_foot;
  for (const char* side : {"r", "l"}) {
    const double z = side[0] == 'r' ? 1.0 : -1.0;  // ground z points to the right: lateral on the right foot
    const int calcn = model.body_index(std::string("calcn_") + side), toes = model.body_index(std::string("toes_") + side);
    const int foot = model.body_index(std::string("foot_") + side);
    auto sphere = [&](const char* name, int body, Eigen::Vector3d location_m, double radius_m) {
      ContactSphere s;
      s.name = std::string(name) + "_" + side;
      s.body = body;
      s.location_m = location_m;
      s.radius_m = radius_m;
      set.spheres.push_back(s);
    };
    first_of_foot.push_back(set.spheres.size());
    if (calcn > 0) {
      // gait2392's calcaneus frame sits at the heel's back, about 1 cm above the sole; five spheres
      // put the heel's two 12 mm either side of its midline and the first and fifth metatarsal heads
      // at the ball's medial and lateral edges.
      const double r = 0.032;
      if (five) {
        sphere("heel_med", calcn, {0.031, 0.010, -z * 0.012}, r);
        sphere("heel_lat", calcn, {0.031, 0.010, z * 0.012}, r);
        sphere("met1", calcn, {0.160, 0.010, -z * 0.022}, r);
        sphere("met5", calcn, {0.150, 0.010, z * 0.035}, r);
      } else {
        sphere("heel", calcn, {0.031, 0.010, 0.0}, r);
      }
      sphere("toes", toes > 0 ? toes : calcn, toes > 0 ? Eigen::Vector3d(0.030, -0.008, z * 0.005) : Eigen::Vector3d(0.17, 0.010, z * 0.005), r);
    } else if (foot > 0) {
      // The fixture walker's foot frame is at the ankle; its sole is 7 cm below.
      const double r = 0.03;
      if (five) {
        sphere("heel_med", foot, {0.0, -0.04, -z * 0.02}, r);
        sphere("heel_lat", foot, {0.0, -0.04, z * 0.02}, r);
        sphere("met1", foot, {0.13, -0.04, -z * 0.025}, r);
        sphere("met5", foot, {0.12, -0.04, z * 0.035}, r);
      } else {
        sphere("heel", foot, {0.0, -0.04, 0.0}, r);
      }
      sphere("toes", foot, {0.16, -0.04, 0.0}, r);
    } else {
      first_of_foot.pop_back();
    }
  }
  // The foot stands flat in the model's default pose, so there every sphere's bottom is put level
  // with the heel's: on scaled gait2392 models the locations above alone left the toes ~2 cm lower,
  // and subject01's recorded stance never brought the heels within 23 mm of the ground (measured).
  KinematicsWorkspace<double> kws(model);
  const Eigen::VectorXd q = model.default_coordinates();
  forward_kinematics(model, q.data(), kws);
  auto bottom = [&](const ContactSphere& s) { return sphere_centre_m(kws, s).y() - s.radius_m; };
  first_of_foot.push_back(set.spheres.size());
  for (std::size_t f = 0; f + 1 < first_of_foot.size(); ++f)
    for (std::size_t i = first_of_foot[f] + 1; i < first_of_foot[f + 1]; ++i) {
      ContactSphere& s = set.spheres[i];
      const double rise_m = bottom(set.spheres[first_of_foot[f]]) - bottom(s);
      s.location_m += kws.body_in_ground[static_cast<std::size_t>(s.body)].rotation.transpose() * Eigen::Vector3d(0, rise_m, 0);
    }
  return set;
}

}  // namespace cpgait
