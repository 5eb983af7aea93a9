#include "cpgait/ik/inverse_kinematics.h"


#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/coordinate_couplers.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/optim/levenberg_marquardt.h"

namespace cpgait {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;

// Reference coordinate values (from_file tasks) at time t, internal units, linear interpolation.
Eigen::VectorXd reference_row_at(const Model& model, const Storage& ref, const IkTargets& targets, double t) {
  Eigen::VectorXd row = Eigen::VectorXd::Constant(ref.num_columns(), kNaN);
  const auto time = ref.time();
  const int n = ref.num_rows();
  int i = 0;
  while (i + 1 < n && time[i + 1] < t) ++i;
  const int k = std::min(i + 1, n - 1);
  const double span = time[k] - time[i];
  const double a = span > 0 ? std::clamp((t - time[i]) / span, 0.0, 1.0) : 0.0;
  const bool degrees = ref.in_degrees.value_or(true);
  for (const auto& c : targets.coordinates) {
    if (c.reference_column < 0) continue;
    double v = (1 - a) * ref.data(i, c.reference_column) + a * ref.data(k, c.reference_column);
    if (degrees && model.coordinates[c.coordinate].is_angle()) v *= kPi / 180.0;
    row[c.reference_column] = v;
  }
  return row;
}

// Residuals: sqrt(w) * (p_model - p_measured) per marker (zero where the marker is missing), then
// sqrt(w) * (q - q_task) per coordinate task. Parameters: the free coordinates (neither locked nor set
// by a coupler); coupled ones follow their independent coordinate.
class IkCost {
 public:
  IkCost(const Model& model, const IkTargets& targets, const std::vector<int>& free, const Eigen::VectorXd& q_fixed)
      : model_(model), targets_(targets), free_(free), q_(q_fixed), ws_(model), S_(model),
        free_slot_(model.num_coordinates(), -1) {
    for (std::size_t k = 0; k < free.size(); ++k) free_slot_[free[k]] = static_cast<int>(k);
    coupler_of_.assign(model.num_coordinates(), -1);
    for (std::size_t j = 0; j < model.couplers.size(); ++j) coupler_of_[model.couplers[j].dependent] = static_cast<int>(j);
    for (const auto& m : targets.markers) {
      std::vector<int> slots;
      for (int c : ancestor_coordinates(model, model.markers[m.model_marker].body))
        if (free_slot_[c] >= 0 || (coupler_of_[c] >= 0 && free_slot_[model.couplers[coupler_of_[c]].independent] >= 0))
          slots.push_back(c);
      marker_coordinates_.push_back(std::move(slots));
      sqrt_w_markers_.push_back(std::sqrt(m.weight));
    }
  }

  void set_frame(const MarkerTrial* trial, int frame, const Eigen::VectorXd* reference_row) {
    trial_ = trial;
    frame_ = frame;
    reference_row_ = reference_row;
  }

  int num_residuals() const { return static_cast<int>(3 * targets_.markers.size() + targets_.coordinates.size()); }

  // Residuals and, when J is not null, the Jacobian (row-major).
  void operator()(const double* x, double* residuals, double* J_out) const {
    for (std::size_t k = 0; k < free_.size(); ++k) q_[free_[k]] = x[k];
    apply_coordinate_couplers(model_, q_.data());
    forward_kinematics(model_, q_.data(), ws_);
    // A coupled coordinate moves with its independent one: d/dq_i = scale f'(q_i) d/dq_d.
    auto slot_and_factor = [&](int c) {
      if (free_slot_[c] >= 0) return std::make_pair(free_slot_[c], 1.0);
      const CoordinateCoupler& cc = model_.couplers[coupler_of_[c]];
      return std::make_pair(free_slot_[cc.independent], cc.scale * cc.function.derivative(q_[cc.independent]));
    };
    const bool want_j = J_out != nullptr;
    const int nf = static_cast<int>(free_.size());
    if (want_j) {
      motion_subspace(model_, q_.data(), ws_, S_);
      std::fill(J_out, J_out + static_cast<std::size_t>(num_residuals()) * nf, 0.0);
    }
    for (std::size_t i = 0; i < targets_.markers.size(); ++i) {
      const auto& m = targets_.markers[i];
      const auto measured = trial_->position_m(frame_, m.trial_marker);
      double* r = residuals + 3 * i;
      if (std::isnan(measured[0])) {
        r[0] = r[1] = r[2] = 0.0;
        continue;
      }
      const Eigen::Vector3d p = marker_position(model_, m.model_marker, ws_);
      const double sw = sqrt_w_markers_[i];
      for (int a = 0; a < 3; ++a) r[a] = sw * (p[a] - measured[a]);
      if (!want_j) continue;
      double* J = J_out + 3 * i * nf;
      for (int c : marker_coordinates_[i]) {
        const auto [k, factor] = slot_and_factor(c);
        const Eigen::Vector3d d = factor * point_velocity_column(S_, c, p);
        J[k] += sw * d[0];
        J[nf + k] += sw * d[1];
        J[2 * nf + k] += sw * d[2];
      }
    }
    const int base = static_cast<int>(3 * targets_.markers.size());
    for (std::size_t i = 0; i < targets_.coordinates.size(); ++i) {
      const auto& c = targets_.coordinates[i];
      const double target = c.reference_column >= 0 ? (*reference_row_)[c.reference_column] : c.value;
      const double sw = std::sqrt(c.weight);
      residuals[base + i] = sw * (q_[c.coordinate] - target);
      const bool moves = free_slot_[c.coordinate] >= 0 ||
                         (coupler_of_[c.coordinate] >= 0 && free_slot_[model_.couplers[coupler_of_[c.coordinate]].independent] >= 0);
      if (want_j && moves) {
        const auto [k, factor] = slot_and_factor(c.coordinate);
        J_out[(base + i) * nf + k] = sw * factor;
      }
    }
  }

 private:
  const Model& model_;
  const IkTargets& targets_;
  const std::vector<int>& free_;
  mutable Eigen::VectorXd q_;
  mutable KinematicsWorkspace<double> ws_;
  mutable MotionSubspace S_;
  std::vector<int> free_slot_;
  std::vector<int> coupler_of_;  // per coordinate: the coupler that sets it, or -1
  std::vector<std::vector<int>> marker_coordinates_;
  std::vector<double> sqrt_w_markers_;
  const MarkerTrial* trial_ = nullptr;
  int frame_ = 0;
  const Eigen::VectorXd* reference_row_ = nullptr;
};

}  // namespace

IkTargets make_ik_targets(const Model& model, const MarkerTrial& trial, const IkTaskSet& tasks,
                          const IkOptions& options, const Storage* coordinate_reference) {
  IkTargets t;
  auto add_marker = [&](const std::string& name, double weight) {
    const int mm = model.marker_index(name), tm = trial.marker_index(name);
    if (mm < 0 || tm < 0) {
      t.warnings.push_back("marker '" + name + "' is " + (mm < 0 ? "not in the model" : "not in the trial") +
                           "; not tracked");
      return;
    }
    if (weight > 0) t.markers.push_back({mm, tm, weight});
  };
  if (tasks.markers.empty()) {
    for (const auto& mk : model.markers) {
      if (trial.marker_index(mk.name) >= 0) add_marker(mk.name, options.default_marker_weight);
    }
  } else {
    for (const auto& mt : tasks.markers)
      if (mt.apply) add_marker(mt.name, mt.weight);
  }
  for (const auto& name : trial.marker_names)
    if (model.marker_index(name) < 0) t.warnings.push_back("trial marker '" + name + "' is not in the model; ignored");
  for (const auto& ct : tasks.coordinates) {
    if (!ct.apply || ct.weight <= 0) continue;
    const int c = model.coordinate_index(ct.name);
    if (c < 0) throw InputError("IK tasks", 0, ct.name, "coordinate task names a coordinate the model does not have");
    IkTargets::CoordinateTarget target{c, ct.weight, model.coordinates[c].default_value, -1};
    if (ct.value_type == IkCoordinateTask::ValueType::kManualValue) target.value = ct.value;
    if (ct.value_type == IkCoordinateTask::ValueType::kFromFile) {
      if (!coordinate_reference)
        throw InputError("IK tasks", 0, ct.name, "task is from_file but no coordinate file was given");
      target.reference_column = coordinate_reference->column(ct.name);
      if (target.reference_column < 0)
        throw InputError("coordinate file", 0, ct.name, "the coordinate file has no column for this task");
    }
    t.coordinates.push_back(target);
  }
  if (t.markers.empty())
    throw InputError(trial.name, 0, "markers", "no marker is both in the model and in the trial with a positive weight");
  return t;
}

double ik_objective(const Model& model, const IkTargets& targets, const MarkerTrial& trial, int frame,
                    const Eigen::VectorXd& q, const Eigen::VectorXd* reference_row) {
  KinematicsWorkspace<double> ws(model);
  forward_kinematics(model, q.data(), ws);
  double f = 0;
  for (const auto& m : targets.markers) {
    const auto measured = trial.position_m(frame, m.trial_marker);
    if (std::isnan(measured[0])) continue;
    f += m.weight * (marker_position(model, m.model_marker, ws) - measured).squaredNorm();
  }
  for (const auto& c : targets.coordinates) {
    const double target = c.reference_column >= 0 ? (*reference_row)[c.reference_column] : c.value;
    f += c.weight * std::pow(q[c.coordinate] - target, 2);
  }
  return f;
}

IkResult inverse_kinematics(const Model& model, const MarkerTrial& trial, const IkTaskSet& tasks,
                            const IkOptions& options, const Storage* coordinate_reference, Progress* progress) {
  IkResult result;
  const IkTargets targets = make_ik_targets(model, trial, tasks, options, coordinate_reference);
  result.summary.warnings = targets.warnings;

  std::vector<int> frames;
  for (int f = 0; f < trial.num_frames(); ++f) {
    const double t = trial.time_s[f];
    if (options.time_range_s && (t < options.time_range_s->first - 1e-9 || t > options.time_range_s->second + 1e-9))
      continue;
    frames.push_back(f);
  }
  if (frames.empty()) throw InputError(trial.name, 0, "time_range", "no frame of the trial lies in the requested time range");

  const int nq = model.num_coordinates();
  const std::vector<int> free = free_coordinates(model);
  std::vector<int> coupled(nq, -1);  // per coordinate: its independent one when a coupler sets it
  for (const auto& cc : model.couplers) coupled[cc.dependent] = cc.independent;
  Eigen::VectorXd q = model.default_coordinates();
  apply_coordinate_couplers(model, q.data());
  IkCost cost(model, targets, free, q);
  Eigen::VectorXd x(free.size()), lo(free.size()), hi(free.size());
  for (std::size_t k = 0; k < free.size(); ++k) {
    const Coordinate& c = model.coordinates[free[k]];
    const bool bound = options.bounds == IkOptions::Bounds::kAllRanges ||
                       (options.bounds == IkOptions::Bounds::kClampedOnly && c.clamped);
    const bool has_range = bound && c.range_min > -1e29;
    lo[k] = has_range ? c.range_min : -std::numeric_limits<double>::infinity();
    hi[k] = has_range ? c.range_max : std::numeric_limits<double>::infinity();
    x[k] = std::clamp(q[free[k]], lo[k], hi[k]);
  }
  LevenbergMarquardtOptions lm;
  lm.function_tolerance = options.function_tolerance;
  lm.gradient_tolerance = options.gradient_tolerance;
  lm.parameter_tolerance = options.parameter_tolerance;
  lm.max_iterations = options.max_iterations;
  LevenbergMarquardtWorkspace lm_workspace;
  const ResidualFunction residuals = [&cost](const double* xs, double* r, double* J) { cost(xs, r, J); };

  const int nm = static_cast<int>(targets.markers.size());
  const int nf = static_cast<int>(frames.size());
  result.q.resize(nf, nq);
  result.marker_error_m.resize(nf, nm);
  result.objective.resize(nf);
  result.total_squared_error_m2.resize(nf);
  result.marker_rms_m.resize(nf);
  result.marker_max_m.resize(nf);
  result.worst_marker.assign(nf, -1);
  for (const auto& m : targets.markers) result.marker_names.push_back(model.markers[m.model_marker].name);

  // Which targets see each free coordinate: a coordinate none of this frame's markers depends on is
  // held at its last value instead of extrapolated, so it cannot drift (and wind past 2 pi) while its
  // segment is out of view.
  std::vector<std::vector<int>> markers_seeing(free.size());
  for (int m = 0; m < static_cast<int>(targets.markers.size()); ++m)
    for (int c : ancestor_coordinates(model, model.markers[targets.markers[m].model_marker].body))
      for (std::size_t k = 0; k < free.size(); ++k)
        if (free[k] == c || free[k] == coupled[c]) markers_seeing[k].push_back(m);
  std::vector<bool> coordinate_task(free.size(), false);
  for (const auto& t : targets.coordinates)
    for (std::size_t k = 0; k < free.size(); ++k) coordinate_task[k] = coordinate_task[k] || free[k] == t.coordinate || free[k] == coupled[t.coordinate];

  KinematicsWorkspace<double> ws(model);
  Eigen::VectorXd reference_row;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < nf; ++i) {
    if (progress && progress->cancelled()) throw std::runtime_error("inverse kinematics cancelled");
    const int f = frames[i];
    if (coordinate_reference) reference_row = reference_row_at(model, *coordinate_reference, targets, trial.time_s[f]);
    cost.set_frame(&trial, f, coordinate_reference ? &reference_row : nullptr);
    // Warm start: extrapolate from the previous solutions (smooth motion), within bounds: linearly
    // from two, or quadratically from three where that predicted the last frame better. Densely
    // sampled, the quadratic guess saves iterations; across frames far apart (the scale fit's ten
    // from a walk) it overshoots into other minima.
    if (i >= 2) {
      bool quadratic = false;
      if (i >= 4) {
        double linear_miss = 0, quadratic_miss = 0;
        for (int c : free) {
          const double last = result.q(i - 1, c), a = result.q(i - 2, c), b = result.q(i - 3, c), d = result.q(i - 4, c);
          linear_miss += std::pow(2.0 * a - b - last, 2);
          quadratic_miss += std::pow(3.0 * (a - b) + d - last, 2);
        }
        quadratic = quadratic_miss < linear_miss;
      }
      for (std::size_t k = 0; k < free.size(); ++k) {
        const bool seen = coordinate_task[k] || std::any_of(markers_seeing[k].begin(), markers_seeing[k].end(), [&](int m) {
                            return !std::isnan(trial.position_m(f, targets.markers[static_cast<std::size_t>(m)].trial_marker)[0]);
                          });
        const int c = free[k];
        const double guess = !seen      ? result.q(i - 1, c)
                             : quadratic ? 3.0 * (result.q(i - 1, c) - result.q(i - 2, c)) + result.q(i - 3, c)
                                         : 2.0 * result.q(i - 1, c) - result.q(i - 2, c);
        x[k] = std::clamp(guess, lo[k], hi[k]);
      }
    }
    const LevenbergMarquardtSummary s = levenberg_marquardt(residuals, cost.num_residuals(), lo, hi, lm, x, lm_workspace);
    // Warm start: x keeps this frame's solution for the next.
    for (std::size_t k = 0; k < free.size(); ++k) q[free[k]] = x[k];
    apply_coordinate_couplers(model, q.data());
    result.summary.total_iterations += s.iterations;
    result.summary.max_iterations_in_a_frame = std::max(result.summary.max_iterations_in_a_frame, s.iterations);
    if (!s.converged) ++result.summary.frames_not_converged;
    result.q.row(i) = q.transpose();
    result.objective[i] = 2.0 * s.final_cost;

    forward_kinematics(model, q.data(), ws);
    double sum2 = 0, worst = -1;
    int present = 0;
    for (int m = 0; m < nm; ++m) {
      const auto measured = trial.position_m(f, targets.markers[m].trial_marker);
      if (std::isnan(measured[0])) {
        result.marker_error_m(i, m) = kNaN;
        continue;
      }
      const double e = (marker_position(model, targets.markers[m].model_marker, ws) - measured).norm();
      result.marker_error_m(i, m) = e;
      sum2 += e * e;
      ++present;
      if (e > worst) {
        worst = e;
        result.worst_marker[i] = m;
      }
    }
    result.time_s.push_back(trial.time_s[f]);
    result.total_squared_error_m2[i] = sum2;
    result.marker_rms_m[i] = present ? std::sqrt(sum2 / present) : kNaN;
    result.marker_max_m[i] = present ? worst : kNaN;
    if (progress) progress->report(double(i + 1) / nf, "inverse kinematics");
  }
  result.summary.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.summary.frames = nf;
  result.summary.mean_marker_rms_m = result.marker_rms_m.mean();
  result.summary.max_marker_rms_m = result.marker_rms_m.maxCoeff();
  result.summary.max_marker_error_m = result.marker_max_m.maxCoeff();
  if (result.summary.frames_not_converged)
    result.summary.warnings.push_back(std::to_string(result.summary.frames_not_converged) +
                                      " frames stopped before the solver's convergence tests were met");
  return result;
}

std::string IkSummary::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "IK: %d frames in %.3f s (%.0f frames/s), %d iterations (max %d in a frame), %d not converged; "
                "marker RMS mean %.2f mm, max %.2f mm; largest marker error %.2f mm",
                frames, solve_seconds, frames_per_second(), total_iterations, max_iterations_in_a_frame,
                frames_not_converged, mean_marker_rms_m * 1e3, max_marker_rms_m * 1e3, max_marker_error_m * 1e3);
  return buf;
}

Storage ik_coordinates_table(const Model& model, const IkResult& result, const std::string& name) {
  Storage s = make_storage(name, coordinate_names(model), result.time_s, coordinates_in_file_units(model, result.q), true);
  s.extra_header = {"", "Units are S.I. units (second, meters, Newtons, ...)", "Angles are in degrees.", ""};
  return s;
}

Storage ik_marker_errors_table(const IkResult& result) {
  std::vector<std::string> labels = {"total_squared_error", "marker_error_RMS", "marker_error_max", "worst_marker"};
  labels.insert(labels.end(), result.marker_names.begin(), result.marker_names.end());
  const Eigen::Index nf = result.q.rows(), nm = static_cast<Eigen::Index>(result.marker_names.size());
  Eigen::MatrixXd values(nf, 4 + nm);
  for (Eigen::Index i = 0; i < nf; ++i) {
    values.row(i).head<4>() << result.total_squared_error_m2[i], result.marker_rms_m[i], result.marker_max_m[i],
        result.worst_marker[i] + 1;
    values.row(i).tail(nm) = result.marker_error_m.row(i);
  }
  Storage s = make_storage("Model Marker Errors from IK", labels, result.time_s, values, false);
  // STO cells are numbers, so the worst marker is given by position; OpenSim readers ignore the
  // columns after its own three.
  s.extra_header = {"Errors in metres. worst_marker: 1-based position of the frame's largest error among the",
                    "marker columns that follow it (0 when no marker was seen)."};
  return s;
}

}  // namespace cpgait
