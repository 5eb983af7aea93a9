#include "cpgait/dynamics/inverse_dynamics.h"

#include <algorithm>

#include <chrono>
#include <cstdio>

#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/capture/function.h"
#include "cpgait/signal/lowpass.h"

namespace cpgait {
namespace {

// A column for a coordinate: its bare name, or OpenSim 4's full path "/jointset/j/name/value".
int coordinate_column(const Storage& s, const std::string& name) {
  const int c = s.column(name);
  if (c >= 0) return c;
  const std::string suffix = "/" + name + "/value";
  for (int i = 0; i < s.num_columns(); ++i)
    if (s.labels[i].size() > suffix.size() && s.labels[i].compare(s.labels[i].size() - suffix.size(), suffix.size(), suffix) == 0)
      return i;
  return -1;
}

}  // namespace

void trajectories_at(const CoordinateTrajectories& k, double t, Eigen::VectorXd& q, Eigen::VectorXd& qd,
                     Eigen::VectorXd& qdd) {
  const auto& ts = k.time_s;
  const int n = static_cast<int>(ts.size());
  if (n == 1) {
    q = k.q.row(0).transpose();
    qd = k.qd.row(0).transpose();
    qdd = k.qdd.row(0).transpose();
    return;
  }
  const int i = std::clamp(static_cast<int>(std::upper_bound(ts.begin(), ts.end(), t) - ts.begin()) - 1, 0, n - 2);
  const double w = std::clamp((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0);
  q = ((1 - w) * k.q.row(i) + w * k.q.row(i + 1)).transpose();
  qd = ((1 - w) * k.qd.row(i) + w * k.qd.row(i + 1)).transpose();
  qdd = ((1 - w) * k.qdd.row(i) + w * k.qdd.row(i + 1)).transpose();
}

CoordinateTrajectories coordinate_trajectories(const Model& model, const Storage& coords,
                                               const InverseDynamicsOptions& options) {
  CoordinateTrajectories out;
  out.warnings = coords.warnings;
  const int n = coords.num_rows(), nq = model.num_coordinates();
  if (n < 4) throw InputError(coords.name, 0, "nRows", "a coordinates file needs at least 4 rows to differentiate");
  bool degrees = options.assume_degrees_when_unspecified;
  if (coords.in_degrees) degrees = *coords.in_degrees;
  else out.warnings.push_back("the coordinates file does not say inDegrees; read as " + std::string(degrees ? "degrees" : "radians"));
  if (!degrees) {
    // OpenSim 2.x wrote degrees under inDegrees=no (the gait2392 RRA and CMC outputs): no joint angle
    // in radians goes past 2 pi, so such a column means the header is wrong.
    for (const auto& co : model.coordinates) {
      const int col = coordinate_column(coords, co.name);
      if (col < 0 || !co.is_angle()) continue;
      const double peak = coords.data.col(col).cwiseAbs().maxCoeff();
      if (peak > 2 * M_PI + 0.01) {
        degrees = true;
        out.warnings.push_back("the coordinates file says inDegrees=no but " + co.name + " reaches " + std::to_string(peak) +
                               ", which only makes sense in degrees: read as degrees");
        break;
      }
    }
  }
  const Eigen::VectorXd time = coords.time();
  const std::vector<double> sample_times(time.data(), time.data() + n);
  const double dt = (time[n - 1] - time[0]) / (n - 1);
  bool uniform = true;
  for (int i = 1; i < n; ++i) uniform = uniform && std::abs(time[i] - time[i - 1] - dt) <= 1e-3 * dt + 1e-9;
  if (!uniform)
    out.warnings.push_back("sample times are unevenly spaced; resampled at their mean interval before differentiating");

  // Times to report: requested ones, or the samples, within the time range and the data.
  const double t_first = options.time_range_s ? options.time_range_s->first : time[0];
  const double t_last = options.time_range_s ? options.time_range_s->second : time[n - 1];
  for (double t : options.output_times_s.empty() ? sample_times : options.output_times_s)
    if (t >= t_first - 1e-6 && t <= t_last + 1e-6 && t >= time[0] - 1e-9 && t <= time[n - 1] + 1e-9) out.time_s.push_back(t);
  if (out.time_s.empty()) throw InputError(coords.name, 0, "time_range", "no sample lies in the requested time range");
  // OpenSim evaluates its padded (reflected) data outside the samples; cpgait reports only times it
  // has data for, and says so.
  if (options.time_range_s && (options.time_range_s->first < time[0] - 1e-6 || options.time_range_s->second > time[n - 1] + 1e-6)) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "the requested time range %.4g-%.4g s extends past the coordinates (%.4g-%.4g s); computed where there is data",
                  options.time_range_s->first, options.time_range_s->second, time[0], time[n - 1]);
    out.warnings.emplace_back(buf);
  }
  const int m = static_cast<int>(out.time_s.size());
  out.q.resize(m, nq);
  out.qd.resize(m, nq);
  out.qdd.resize(m, nq);
  out.recorded_time_s = sample_times;
  out.q_recorded.resize(n, nq);

  // Padding keeps the filter's start-up transient and the spline's end effects out of the data.
  const int pad = options.lowpass_cutoff_hz >= 0 ? n / 2 : 0;
  std::vector<double> knots(n + 2 * pad);
  for (int i = 0; i < n + 2 * pad; ++i) knots[i] = time[0] + (i - pad) * dt;
  for (int c = 0; c < nq; ++c) {
    const Coordinate& co = model.coordinates[c];
    const int col = coordinate_column(coords, co.name);
    if (col < 0) {
      out.warnings.push_back("coordinate '" + co.name + "' is not in the coordinates file; held at its default");
      out.q_recorded.col(c).setConstant(co.default_value);
      out.q.col(c).setConstant(co.default_value);
      out.qd.col(c).setZero();
      out.qdd.col(c).setZero();
      continue;
    }
    Eigen::VectorXd x = coords.data.col(col);
    if (degrees && co.is_angle()) x *= M_PI / 180.0;
    out.q_recorded.col(c) = x;
    if (!uniform) {
      const Function raw = Function::simm_spline(sample_times, std::vector<double>(x.data(), x.data() + n));
      for (int i = 0; i < n; ++i) x[i] = raw.value(knots[pad + i]);
    }
    if (options.lowpass_cutoff_hz >= 0) x = lowpass_butterworth3_zero_phase(pad_odd_reflection(x, pad), dt, options.lowpass_cutoff_hz);
    const Function spline = Function::simm_spline(knots, std::vector<double>(x.data(), x.data() + x.size()));
    for (int k = 0; k < m; ++k) {
      const double t = out.time_s[k];
      out.q(k, c) = spline.value(t);
      out.qd(k, c) = spline.derivative(t);
      out.qdd(k, c) = spline.second_derivative(t);
    }
  }
  return out;
}

void inverse_dynamics_frame(const Model& model, const double* q, const double* qd, const double* qdd, double t,
                            const AppliedLoads* loads, InverseDynamicsFrameWorkspace& ws, double* tau) {
  static const std::vector<Vector6d> kNone;
  if (loads) {
    forward_kinematics(model, q, ws.kinematics);
    loads->wrenches_at(t, ws.kinematics, ws.external);
  }
  rnea(model, q, qd, qdd, loads ? ws.external : kNone, ws.dynamics, tau);
  // OpenSim's ID keeps the model's passive forces applied (only muscles are excluded by default):
  // the joint moments are what remains to be supplied.
  if (!model.coordinate_limit_forces.empty()) {
    for (int i = 0; i < model.num_coordinates(); ++i) ws.passive[i] = 0.0;
    add_passive_generalized_forces(model, q, qd, ws.passive.data());
    for (int i = 0; i < model.num_coordinates(); ++i) tau[i] -= ws.passive[i];
  }
}

InverseDynamicsResult inverse_dynamics(const Model& model, const Storage& coordinates, const AppliedLoads* loads,
                                       const InverseDynamicsOptions& options, Progress* progress) {
  InverseDynamicsResult result;
  result.kinematics = coordinate_trajectories(model, coordinates, options);
  result.summary.warnings = result.kinematics.warnings;
  const auto& k = result.kinematics;
  const int m = static_cast<int>(k.time_s.size()), nq = model.num_coordinates();
  if (loads && (k.time_s.front() < loads->start_time_s() - 1e-6 || k.time_s.back() > loads->end_time_s() + 1e-6))
    result.summary.warnings.push_back("the load data does not cover the whole time range; end values are held");
  result.time_s = k.time_s;
  result.generalized_forces.resize(m, nq);
  InverseDynamicsFrameWorkspace ws(model);
  Eigen::VectorXd q(nq), qd(nq), qdd(nq), tau(nq);
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < m; ++i) {
    if (progress && progress->cancelled()) throw std::runtime_error("inverse dynamics cancelled");
    q = k.q.row(i).transpose();
    qd = k.qd.row(i).transpose();
    qdd = k.qdd.row(i).transpose();
    inverse_dynamics_frame(model, q.data(), qd.data(), qdd.data(), k.time_s[i], loads, ws, tau.data());
    result.generalized_forces.row(i) = tau.transpose();
    if (progress) progress->report(double(i + 1) / m, "inverse dynamics");
  }
  result.summary.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.summary.frames = m;
  return result;
}

std::string InverseDynamicsSummary::BriefReport() const {
  char buf[256];
  std::snprintf(buf, sizeof buf, "ID: %d frames in %.4f s (%.0f frames/s)", frames, solve_seconds, frames_per_second());
  return buf;
}

Storage inverse_dynamics_table(const Model& model, const InverseDynamicsResult& result) {
  std::vector<std::string> labels;
  for (const auto& c : model.coordinates) labels.push_back(c.name + (c.is_angle() ? "_moment" : "_force"));
  return make_storage("Inverse Dynamics", labels, result.time_s, result.generalized_forces, false);
}

}  // namespace cpgait
