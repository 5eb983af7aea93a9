#include "cpgait/capture/ground_reactions.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include "cpgait/capture/force_plates.h"

namespace cpgait {
namespace {

// 'r' or 'l' for a heel marker's name (a subject prefix "Name:" dropped), else 0.
char heel_side(std::string name) {
  if (const auto colon = name.rfind(':'); colon != std::string::npos) name = name.substr(colon + 1);
  std::string u;
  for (char c : name) u += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (u.find("HEE") == std::string::npos && u.find("FCC") == std::string::npos && u.find("CALC") == std::string::npos) return 0;
  auto starts = [&](const char* p) { return u.rfind(p, 0) == 0; };
  auto ends = [&](const char* p) { const std::string s(p); return u.size() >= s.size() && u.compare(u.size() - s.size(), s.size(), s) == 0; };
  if (starts("RIGHT") || starts("R_") || starts("R.") || starts("R ") || ends("_R") || ends(" R")) return 'r';
  if (starts("LEFT") || starts("L_") || starts("L.") || starts("L ") || ends("_L") || ends(" L")) return 'l';
  if (u.size() > 1 && (u[0] == 'R' || u[0] == 'L') && std::isalpha(static_cast<unsigned char>(u[1])) && u.substr(1, 3) != "IGH")
    return u[0] == 'R' ? 'r' : 'l';  // RHEE, LHEE
  return 0;
}

std::string fmt_time(double t) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f s", t);
  return b;
}

}  // namespace

GroundReactions ground_reactions(const C3dFile& f, const Eigen::Matrix3d& to_opensim, const GroundReactionOptions& o) {
  GroundReactions g;
  const std::vector<ForcePlate> plates = read_force_plates(f);
  const Eigen::Index n = f.analog.values.rows();
  if (plates.empty() || n == 0) {
    g.warnings.push_back(f.name + ": no force plates");
    return g;
  }
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  up[c3d_vertical_axis(f)] = 1.0;
  const double rate = f.analog.rate_hz, start_s = f.markers.time_s.empty() ? 0.0 : f.markers.time_s.front();
  std::vector<double> time(static_cast<std::size_t>(n));
  for (Eigen::Index s = 0; s < n; ++s) time[static_cast<std::size_t>(s)] = start_s + static_cast<double>(s) / rate;
  int heel[2] = {-1, -1};  // right, left
  for (int m = 0; m < f.markers.num_markers(); ++m)
    if (const char side = heel_side(f.markers.marker_names[static_cast<std::size_t>(m)]); side && heel[side == 'r' ? 0 : 1] < 0)
      heel[side == 'r' ? 0 : 1] = m;
  const int per_frame = std::max(1, f.analog.samples_per_frame);

  struct Group {
    int plate;
    char foot;
    std::vector<std::pair<Eigen::Index, Eigen::Index>> runs;
  };
  std::vector<Group> groups;
  std::vector<PlateForces> forces;
  for (const ForcePlate& p : plates) {
    forces.push_back(plate_forces(f, p, up, o.threshold_N, o.lowpass_hz));
    const PlateForces& pf = forces.back();
    g.negated_any |= pf.negated;
    std::vector<Group> mine;
    for (Eigen::Index s = 0; s < n;) {
      if (!(pf.force_N.col(s).dot(up) > 0)) {
        ++s;
        continue;
      }
      Eigen::Index e = s;
      double peak = 0;
      while (e < n && pf.force_N.col(e).dot(up) > 0) peak = std::max(peak, pf.force_N.col(e++).dot(up));
      if (static_cast<double>(e - s) / rate < o.min_stance_s) {
        s = e;
        continue;
      }
      Stance st{p.number, '?', time[static_cast<std::size_t>(s)], time[static_cast<std::size_t>(e - 1)], peak};
      if (auto it = o.plate_foot.find(p.number); it != o.plate_foot.end()) {
        st.foot = it->second;
      } else {
        double d[2] = {0, 0};
        int seen[2] = {0, 0};
        for (Eigen::Index k = s; k < e; k += per_frame) {
          const int frame = static_cast<int>(k / per_frame);
          if (frame >= f.markers.num_frames()) break;
          for (int side = 0; side < 2; ++side) {
            if (heel[side] < 0) continue;
            const Eigen::Vector3d h = f.markers.position_m(frame, heel[side]);
            if (!h.allFinite()) continue;
            const Eigen::Vector3d r = h - pf.cop_m.col(k);
            d[side] += (r - r.dot(up) * up).norm();
            ++seen[side];
          }
        }
        if (seen[0] || seen[1]) {
          const double dr = seen[0] ? d[0] / seen[0] : std::numeric_limits<double>::infinity();
          const double dl = seen[1] ? d[1] / seen[1] : std::numeric_limits<double>::infinity();
          st.foot = dr <= dl ? 'r' : 'l';
        }
      }
      g.stances.push_back(st);
      if (st.foot == '?') {
        g.warnings.push_back("plate " + std::to_string(p.number) + ", stance " + fmt_time(st.begin_s) + "-" + fmt_time(st.end_s) +
                             ": no heel marker tells the foot; not written (name the plate's foot)");
      } else {
        auto it = std::find_if(mine.begin(), mine.end(), [&](const Group& x) { return x.foot == st.foot; });
        if (it == mine.end()) mine.push_back({p.number, st.foot, {}}), it = mine.end() - 1;
        it->runs.emplace_back(s, e);
      }
      s = e;
    }
    if (mine.empty()) g.warnings.push_back("plate " + std::to_string(p.number) + " was not stood on");
    for (auto& m : mine) groups.push_back(std::move(m));
  }

  // Columns per group: force, point, torque, in OpenSim's frame; zero (point at the plate's centre)
  // outside the group's stances.
  std::vector<std::string> labels;
  Eigen::MatrixXd values = Eigen::MatrixXd::Zero(n, 9 * static_cast<Eigen::Index>(groups.size()));
  for (std::size_t gi = 0; gi < groups.size(); ++gi) {
    const Group& gr = groups[gi];
    bool both = false;
    for (const Group& other : groups) both |= other.plate == gr.plate && other.foot != gr.foot;
    const std::string prefix = std::to_string(gr.plate) + (both ? std::string(1, gr.foot) : "") + "_";
    for (const char* kind : {"ground_force_v", "ground_force_p", "ground_torque_"})
      for (const char* axis : {"x", "y", "z"}) labels.push_back(prefix + kind + axis);
    g.loads.emplace_back(prefix, gr.foot == 'r' ? o.right_body : o.left_body);
    const ForcePlate& p = plates[static_cast<std::size_t>(gr.plate - 1)];
    const PlateForces& pf = forces[static_cast<std::size_t>(gr.plate - 1)];
    const Eigen::Index c0 = 9 * static_cast<Eigen::Index>(gi);
    const Eigen::Vector3d centre = to_opensim * p.centre_m;
    for (Eigen::Index s = 0; s < n; ++s) values.block<1, 3>(s, c0 + 3) = centre.transpose();
    for (const auto& [s0, s1] : gr.runs)
      for (Eigen::Index s = s0; s < s1; ++s) {
        values.block<1, 3>(s, c0) = (to_opensim * pf.force_N.col(s)).transpose();
        values.block<1, 3>(s, c0 + 3) = (to_opensim * pf.cop_m.col(s)).transpose();
        values.block<1, 3>(s, c0 + 6) = (to_opensim * pf.free_moment_Nm.col(s)).transpose();
      }
  }
  g.grf = make_storage("ground reactions", labels, time, values, false);
  g.grf.extra_header = {"From the force plates: forces (N) and torques (N m) on the subject, points (m)."};
  if (g.negated_any) g.warnings.push_back("some plates' channels give the force on the plate: negated to the force on the subject");
  return g;
}

std::string external_loads_document(const GroundReactions& g, const std::string& datafile) {
  std::string out = "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40000\">\n\t<ExternalLoads name=\"externalloads\">\n\t\t<objects>\n";
  for (const auto& [prefix, body] : g.loads) {
    const std::string name = "plate" + prefix.substr(0, prefix.size() - 1);
    out += "\t\t\t<ExternalForce name=\"" + name + "\">\n\t\t\t\t<applied_to_body>" + body +
           "</applied_to_body>\n\t\t\t\t<force_expressed_in_body>ground</force_expressed_in_body>\n"
           "\t\t\t\t<point_expressed_in_body>ground</point_expressed_in_body>\n\t\t\t\t<force_identifier>" +
           prefix + "ground_force_v</force_identifier>\n\t\t\t\t<point_identifier>" + prefix +
           "ground_force_p</point_identifier>\n\t\t\t\t<torque_identifier>" + prefix +
           "ground_torque_</torque_identifier>\n\t\t\t\t<data_source_name>Unassigned</data_source_name>\n\t\t\t</ExternalForce>\n";
  }
  return out + "\t\t</objects>\n\t\t<groups />\n\t\t<datafile>" + datafile +
         "</datafile>\n\t\t<external_loads_model_kinematics_file />\n"
         "\t\t<lowpass_cutoff_frequency_for_load_kinematics>-1</lowpass_cutoff_frequency_for_load_kinematics>\n"
         "\t</ExternalLoads>\n</OpenSimDocument>\n";
}

}  // namespace cpgait
