#include "cpgait/scaling/fit_scale_factors.h"

#include <ceres/ceres.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "cpgait/capture/input_error.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/scaling/model_scale_factors.h"
#include "cpgait/scaling/place_markers.h"
#include "cpgait/scaling/scale_model.h"

namespace cpgait {
namespace {

// Which factor block entry scales each body: group g's factors are s[k*g .. k*g+k-1]; -1 for ground.
struct Groups {
  int per_group = 1;  // 1 (one factor for all axes) or 3
  int count = 0;
  std::vector<int> of_body;
  std::vector<std::string> names;

  template <typename T>
  std::vector<Eigen::Matrix<T, 3, 1>> body_scales(const T* s) const {
    std::vector<Eigen::Matrix<T, 3, 1>> out(of_body.size(), Eigen::Matrix<T, 3, 1>::Constant(T(1.0)));
    for (std::size_t b = 0; b < of_body.size(); ++b) {
      const int g = of_body[b];
      if (g < 0) continue;
      if (per_group == 1) out[b].setConstant(s[g]);
      else out[b] << s[3 * g], s[3 * g + 1], s[3 * g + 2];
    }
    return out;
  }
};

// A body with no tracked marker of its own (a talus, toes) takes its parent's factors: nothing on
// it tells its size apart.
Groups make_groups(const Model& m, const ScaleFitOptions& o, const std::vector<bool>& has_markers) {
  Groups g;
  g.per_group = o.per_axis ? 3 : 1;
  g.of_body.assign(m.bodies.size(), -1);
  std::map<std::string, int> by_key;
  for (std::size_t b = 1; b < m.bodies.size(); ++b) {
    std::size_t named = b;
    while (!has_markers[named] && m.joints[m.bodies[named].joint].parent_body != 0)
      named = static_cast<std::size_t>(m.joints[m.bodies[named].joint].parent_body);
    std::string key = m.bodies[named].name;
    if (o.symmetric && key.size() > 2) {
      const std::string tail = key.substr(key.size() - 2);
      if (tail == "_r" || tail == "_l" || tail == "_R" || tail == "_L") key = key.substr(0, key.size() - 2);
    }
    auto [it, inserted] = by_key.try_emplace(key, g.count);
    if (inserted) {
      ++g.count;
      g.names.push_back(key);
    }
    g.of_body[b] = it->second;
  }
  return g;
}

// One marker seen in one frame: sqrt(w) (p_m(q; s) + R_B d_m - x).
struct MarkerResidual {
  const Model* model;
  const Groups* groups;
  int body;
  Eigen::Vector3d location_m, measured_m;
  double sqrt_weight;

  template <typename T>
  bool operator()(T const* const* p, T* r) const {
    std::vector<T> q(p[0], p[0] + model->num_coordinates());
    apply_coordinate_couplers(*model, q.data());
    const auto scales = groups->body_scales(p[1]);
    KinematicsWorkspace<T> ws(*model);
    scaled_forward_kinematics(*model, q.data(), scales.data(), ws);
    const PoseT<T>& B = ws.body_in_ground[body];
    const Eigen::Matrix<T, 3, 1> local = location_m.cast<T>().cwiseProduct(scales[body]) + Eigen::Matrix<T, 3, 1>(p[2][0], p[2][1], p[2][2]);
    const Eigen::Matrix<T, 3, 1> e = B.rotation * local + B.translation_m - measured_m.cast<T>();
    for (int k = 0; k < 3; ++k) r[k] = sqrt_weight * e[k];
    return true;
  }
};

struct OffsetPrior {
  double weight;
  template <typename T>
  bool operator()(const T* d, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = weight * d[k];
    return true;
  }
};

struct ScalePrior {
  double weight_m;
  int size;
  template <typename T>
  bool operator()(T const* const* p, T* r) const {
    for (int k = 0; k < size; ++k) r[k] = weight_m * (p[0][k] - 1.0);
    return true;
  }
};

// The frames of a trial at the given indices, as a trial of their own.
MarkerTrial frames_of(const MarkerTrial& t, const std::vector<int>& frames) {
  MarkerTrial out;
  out.name = t.name;
  out.marker_names = t.marker_names;
  out.data_rate_hz = t.data_rate_hz;
  out.camera_rate_hz = t.camera_rate_hz;
  const int nm = t.num_markers();
  out.positions_m.resize(3, static_cast<Eigen::Index>(frames.size()) * nm);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    out.time_s.push_back(t.time_s[frames[i]]);
    out.frame_numbers.push_back(static_cast<int>(i) + 1);
    out.positions_m.middleCols(static_cast<Eigen::Index>(i) * nm, nm) = t.positions_m.middleCols(static_cast<Eigen::Index>(frames[i]) * nm, nm);
  }
  return out;
}

double marker_rms(const Model& m, const MarkerTrial& frame, const IkTargets& targets, const Eigen::VectorXd& q) {
  KinematicsWorkspace<double> ws(m);
  forward_kinematics(m, q.data(), ws);
  double sum2 = 0;
  int n = 0;
  for (const auto& t : targets.markers) {
    const Eigen::Vector3d x = frame.position_m(0, t.trial_marker);
    if (!x.allFinite()) continue;
    sum2 += (marker_position(m, t.model_marker, ws) - x).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sum2 / n) : 0.0;
}

}  // namespace

std::string ScaleFitSummary::BriefReport() const {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "scale fit: %d frames, %d marker observations, %d parameters, %d iterations, %.3f s; static marker RMS "
                "%.2f mm on the generic model, %.2f mm fitted, %.2f mm with markers placed",
                frames, residuals, parameters, iterations, seconds, 1e3 * static_rms_generic_m, 1e3 * static_rms_fitted_m,
                1e3 * static_rms_placed_m);
  return buf;
}

ScaleFit fit_scale_factors(const Model& generic, const MarkerTrial& static_trial, const IkTaskSet& tasks,
                           const std::vector<const MarkerTrial*>& motion_trials, const ScaleFitOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  ScaleFit fit;
  ScaleFitSummary& sum = fit.summary;
  const int n = generic.num_coordinates();

  // The frames: the static trial averaged, then frames taken evenly from each motion trial; each
  // posed first by IK on the generic model.
  struct Frame {
    MarkerTrial trial;
    IkTargets targets;
    Eigen::VectorXd q;
  };
  std::vector<Frame> frames;
  {
    Frame f;
    f.trial = average_static_frame(static_trial, options.static_time_range_s);
    f.targets = make_ik_targets(generic, f.trial, tasks, IkOptions{});
    if (f.targets.markers.size() < 3)
      throw InputError(static_trial.name, 0, "markers", "the static trial shares fewer than 3 markers with the model");
    const IkResult ik = inverse_kinematics(generic, f.trial, tasks);
    f.q = ik.q.row(0).transpose();
    sum.static_rms_generic_m = ik.marker_rms_m[0];
    sum.warnings = f.targets.warnings;
    frames.push_back(std::move(f));
  }
  for (const MarkerTrial* t : motion_trials) {
    const int nf = t->num_frames(), take = std::min(nf, std::max(1, options.frames_per_motion_trial));
    std::vector<int> picked;
    for (int i = 0; i < take; ++i) picked.push_back(take == 1 ? 0 : static_cast<int>(std::lround(double(i) * (nf - 1) / (take - 1))));
    const MarkerTrial sub = frames_of(*t, picked);
    const IkResult ik = inverse_kinematics(generic, sub, tasks);
    const IkTargets targets = make_ik_targets(generic, sub, tasks, IkOptions{});
    for (int i = 0; i < take; ++i) {
      Frame f;
      f.trial = frames_of(sub, {i});
      f.targets = targets;
      f.q = ik.q.row(i).transpose();
      frames.push_back(std::move(f));
    }
  }

  std::vector<bool> has_markers(generic.bodies.size(), false);
  for (const auto& t : frames[0].targets.markers)
    if (t.weight > 0 && frames[0].trial.position_m(0, t.trial_marker).allFinite()) has_markers[generic.markers[t.model_marker].body] = true;
  const Groups groups = make_groups(generic, options, has_markers);

  // Parameters: one pose per frame, the factors, an offset per model marker.
  std::vector<double> s(static_cast<std::size_t>(groups.count * groups.per_group), 1.0);
  std::vector<Eigen::Vector3d> offsets(generic.markers.size(), Eigen::Vector3d::Zero());
  std::vector<bool> offset_used(generic.markers.size(), false);
  ceres::Problem problem;
  std::vector<int> held;  // locked and coupled coordinates stay where IK put them
  for (int c = 0; c < n; ++c)
    if (generic.coordinates[c].locked) held.push_back(c);
  for (const auto& cp : generic.couplers) held.push_back(cp.dependent);
  for (auto& f : frames) {
    for (const auto& t : f.targets.markers) {
      const Eigen::Vector3d x = f.trial.position_m(0, t.trial_marker);
      if (!x.allFinite() || t.weight <= 0) continue;
      const Marker& mk = generic.markers[t.model_marker];
      auto* cost = new ceres::DynamicAutoDiffCostFunction<MarkerResidual, 4>(
          new MarkerResidual{&generic, &groups, mk.body, mk.location_m, x, std::sqrt(t.weight)});
      cost->AddParameterBlock(n);
      cost->AddParameterBlock(static_cast<int>(s.size()));
      cost->AddParameterBlock(3);
      cost->SetNumResiduals(3);
      problem.AddResidualBlock(cost, nullptr, {f.q.data(), s.data(), offsets[t.model_marker].data()});
      if (!offset_used[t.model_marker]) {
        offset_used[t.model_marker] = true;
        problem.AddResidualBlock(new ceres::AutoDiffCostFunction<OffsetPrior, 3, 3>(new OffsetPrior{options.offset_prior * std::sqrt(t.weight)}),
                                 nullptr, offsets[t.model_marker].data());
        if (mk.fixed) problem.SetParameterBlockConstant(offsets[t.model_marker].data());
      }
      ++sum.residuals;
    }
    if (!held.empty() && problem.HasParameterBlock(f.q.data())) {
      if (static_cast<int>(held.size()) < n) problem.SetManifold(f.q.data(), new ceres::SubsetManifold(n, held));
    }
  }
  {
    auto* prior = new ceres::DynamicAutoDiffCostFunction<ScalePrior, 4>(new ScalePrior{options.scale_prior_m, static_cast<int>(s.size())});
    prior->AddParameterBlock(static_cast<int>(s.size()));
    prior->SetNumResiduals(static_cast<int>(s.size()));
    problem.AddResidualBlock(prior, nullptr, s.data());
  }
  for (int k = 0; k < static_cast<int>(s.size()); ++k) {
    problem.SetParameterLowerBound(s.data(), k, kMinScaleFactor);
    problem.SetParameterUpperBound(s.data(), k, kMaxScaleFactor);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.logging_type = ceres::SILENT;
  so.num_threads = 1;
  ceres::Solver::Summary cs;
  ceres::Solve(so, &problem, &cs);
  sum.iterations = static_cast<int>(cs.iterations.size());
  sum.parameters = cs.num_effective_parameters;
  sum.frames = static_cast<int>(frames.size());
  if (cs.termination_type == ceres::FAILURE) sum.warnings.push_back("scale fit did not converge: " + cs.message);

  fit.factors = groups.body_scales(s.data());
  fit.factors[0].setOnes();
  const Model scaled = scale_model(generic, fit.factors, options.preserve_mass_distribution, options.subject_mass_kg);
  MarkerPlacement p = place_markers(scaled, static_trial, tasks, options.static_time_range_s);
  if (!motion_trials.empty()) {
    // Offsets fitted over the motion too say more than the static frame alone: they are kept.
    p.model = scaled;
    for (std::size_t m = 0; m < p.model.markers.size(); ++m)
      if (offset_used[m]) p.model.markers[m].location_m += offsets[m];
  }
  fit.model = p.model;
  fit.static_pose = p.static_pose;
  sum.static_rms_fitted_m = p.marker_rms_before_m;
  const IkTargets placed = make_ik_targets(fit.model, frames[0].trial, tasks, IkOptions{});
  sum.static_rms_placed_m = marker_rms(fit.model, frames[0].trial, placed, fit.static_pose);
  for (const auto& w : p.warnings) sum.warnings.push_back(w);
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return fit;
}

}  // namespace cpgait
