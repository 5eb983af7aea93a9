#include "cpgait/dynamics/rosenbrock_w.h"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>

namespace cpgait {
namespace {

// The step loop both methods share: the Jacobian prepared at each step's start (and kept through
// retried steps), step-size control, accepted steps reported. attempt(t, h, f0, y) takes the step
// from (t, x) with f0 = f(t, x) into y and returns its scaled error; step_factor(norm) the next
// step's ratio before clamping.
template <typename Attempt, typename StepFactor>
DormandPrinceSummary rosenbrock_steps(const WPrepare& prepare, double t0, double t1, Eigen::VectorXd& x,
                                      const RosenbrockOptions& o, const WStepDone& step_done, Attempt&& attempt,
                                      StepFactor&& step_factor, DormandPrinceSummary& s) {
  const long n = x.size();
  Eigen::VectorXd f0(n), y(n);
  double t = t0;
  double h = std::clamp(o.initial_step_s, o.min_step_s, o.max_step_s);
  if (t1 <= t0) {
    s.last_step_s = h;
    return s;
  }
  bool prepared = false;
  while (t < t1) {
    const double h_unclipped = h;
    bool last = false;
    if (!begin_step(t, t1, o.max_steps, h, last, s)) break;
    if (!prepared) {
      prepare(t, x, f0);
      ++s.evaluations;
      prepared = true;
    }
    const double norm = attempt(t, h, f0, y);
    const double factor = std::clamp(step_factor(norm), 0.2, 5.0);
    if (norm <= 1.0) {
      const double t_next = last ? t1 : t + h;
      if (step_done) step_done(t, x, t_next, y);
      x = y;
      t = t_next;
      prepared = false;
      next_step_after_accept(h, factor, last, h_unclipped, o.max_step_s, s);
    } else if (!next_step_after_reject(h, factor, o.min_step_s, t, s)) {
      break;
    }
  }
  if (s.last_step_s == 0) s.last_step_s = h;
  return s;
}

// ROS34PW2 in the transformed variables u_i = sum_j Gamma_ij k_j (Hairer & Wanner IV.7):
// (I - gamma h J) u_i = gamma h (f(x + sum_j a_ij u_j) + sum_j c_ij u_j / h), x_new = x + sum m_i u_i,
// error sum e_i u_i. Coefficients of Rang & Angermann (2005), as PETSc's TSROSWRA34PW2.
struct Ros34pw2 {
  static constexpr int kStages = 4;
  double gamma = 4.3586652150845900e-01;
  Eigen::Matrix4d a, c;
  Eigen::Vector4d m, e, stage_time;
  Ros34pw2() {
    Eigen::Matrix4d alpha = Eigen::Matrix4d::Zero(), G = Eigen::Matrix4d::Zero();
    alpha(1, 0) = 8.7173304301691801e-01;
    alpha(2, 0) = 8.4457060015369423e-01;
    alpha(2, 1) = -1.1299064236484185e-01;
    alpha(3, 2) = 1.0;
    G.diagonal().setConstant(gamma);
    G(1, 0) = -8.7173304301691801e-01;
    G(2, 0) = -9.0338057013044082e-01;
    G(2, 1) = 5.4180672388095326e-02;
    G(3, 0) = 2.4212380706095346e-01;
    G(3, 1) = -1.2232505839045147e+00;
    G(3, 2) = 5.4526025533510214e-01;
    const Eigen::Vector4d b(2.4212380706095346e-01, -1.2232505839045147e+00, 1.5452602553351020e+00, 4.3586652150845900e-01);
    const Eigen::Vector4d b_embedded(3.7810903145819369e-01, -9.6042292212423178e-02, 5.0000000000000000e-01, 2.1793326075422950e-01);
    const Eigen::Matrix4d Gi = G.inverse();
    a = alpha * Gi;
    c = Eigen::Matrix4d(Gi.diagonal().asDiagonal()) - Gi;
    m = Gi.transpose() * b;
    e = Gi.transpose() * (b - b_embedded);
    stage_time = alpha.rowwise().sum();
  }
};

}  // namespace

DormandPrinceSummary integrate_ros2(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                    double t1, Eigen::VectorXd& x, const RosenbrockOptions& o, const WStepDone& step_done) {
  DormandPrinceSummary s;
  const long n = x.size();
  const double gamma = 1.0 + 1.0 / std::sqrt(2.0);
  Eigen::VectorXd f1(n), k1(n), k2(n), rhs(n);
  auto attempt = [&](double t, double h, const Eigen::VectorXd& f0, Eigen::VectorXd& y) {
    solve(gamma * h, f0, k1);
    y = x + h * k1;
    f(t + h, y, f1);
    ++s.evaluations;
    rhs = f1 - 2.0 * k1;
    solve(gamma * h, rhs, k2);
    // Error: the difference to the first-order solution x + h k1.
    y = x + 1.5 * h * k1 + 0.5 * h * k2;
    rhs = 0.5 * h * (k1 + k2);
    return scaled_rms_error(rhs, x, y, o.relative_tolerance, o.absolute_tolerance);
  };
  auto step_factor = [](double norm) { return 0.9 / std::sqrt(std::max(norm, 1e-10)); };
  return rosenbrock_steps(prepare, t0, t1, x, o, step_done, attempt, step_factor, s);
}

DormandPrinceSummary integrate_ros34pw2(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                        double t1, Eigen::VectorXd& x, const RosenbrockOptions& o, const WStepDone& step_done) {
  static const Ros34pw2 tab;
  DormandPrinceSummary s;
  const long n = x.size();
  std::array<Eigen::VectorXd, Ros34pw2::kStages> u;
  for (auto& ui : u) ui.resize(n);
  Eigen::VectorXd fi(n), stage(n), rhs(n), err(n);
  auto attempt = [&](double t, double h, const Eigen::VectorXd& f0, Eigen::VectorXd& y) {
    for (int i = 0; i < Ros34pw2::kStages; ++i) {
      if (i == 0) {
        rhs = f0;
      } else {
        stage = x;
        for (int j = 0; j < i; ++j) stage += tab.a(i, j) * u[j];
        f(t + tab.stage_time[i] * h, stage, fi);
        ++s.evaluations;
        rhs = fi;
        for (int j = 0; j < i; ++j) rhs += (tab.c(i, j) / h) * u[j];
      }
      solve(tab.gamma * h, rhs, u[i]);
      u[i] *= tab.gamma * h;
    }
    y = x;
    err.setZero();
    for (int i = 0; i < Ros34pw2::kStages; ++i) {
      y += tab.m[i] * u[i];
      err += tab.e[i] * u[i];
    }
    return scaled_rms_error(err, x, y, o.relative_tolerance, o.absolute_tolerance);
  };
  auto step_factor = [](double norm) { return 0.9 * std::cbrt(1.0 / std::max(norm, 1e-10)); };
  return rosenbrock_steps(prepare, t0, t1, x, o, step_done, attempt, step_factor, s);
}

DormandPrinceSummary integrate_linearly_implicit_euler(const OdeFunction&, const WPrepare& prepare, const WSolve& solve, double t0,
                                                       double t1, Eigen::VectorXd& x, const RosenbrockOptions& o, const WStepDone& step_done) {
  DormandPrinceSummary s;
  const double max_step_s = std::max(o.max_step_s, o.min_step_s);
  s.last_step_s = max_step_s;
  if (!(t1 > t0)) return s;
  const long steps = std::max(1L, static_cast<long>(std::ceil((t1 - t0) / max_step_s - 1e-9)));
  if (steps > o.max_steps) {
    s.success = false;
    s.message = "too many integrator steps";
    return s;
  }
  const double h = (t1 - t0) / static_cast<double>(steps);
  Eigen::VectorXd f0(x.size()), k(x.size()), y(x.size());
  double t = t0;
  for (long i = 1; i <= steps; ++i) {
    prepare(t, x, f0);
    ++s.evaluations;
    solve(h, f0, k);
    y = x + h * k;
    const double t_next = i < steps ? t0 + static_cast<double>(i) * h : t1;
    if (step_done) step_done(t, x, t_next, y);
    x = y;
    t = t_next;
    ++s.accepted_steps;
  }
  s.last_step_s = h;
  return s;
}

DormandPrinceSummary integrate_w_method(WMethod method, const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                        double t1, Eigen::VectorXd& x, const RosenbrockOptions& o, const WStepDone& step_done) {
  switch (method) {
    case WMethod::kRos34pw2: return integrate_ros34pw2(f, prepare, solve, t0, t1, x, o, step_done);
    case WMethod::kLinearlyImplicitEuler: return integrate_linearly_implicit_euler(f, prepare, solve, t0, t1, x, o, step_done);
    case WMethod::kRos2: break;
  }
  return integrate_ros2(f, prepare, solve, t0, t1, x, o, step_done);
}

std::string w_method_name(WMethod method) {
  switch (method) {
    case WMethod::kRos34pw2: return "ros34pw2";
    case WMethod::kLinearlyImplicitEuler: return "linearly_implicit_euler";
    case WMethod::kRos2: break;
  }
  return "rosenbrock";
}

WMethod at_tolerance(WMethod method) { return method == WMethod::kLinearlyImplicitEuler ? WMethod::kRos34pw2 : method; }

std::optional<WMethod> w_method_named(std::string_view name) {
  if (name == "ros34pw2") return WMethod::kRos34pw2;
  if (name == "linearly_implicit_euler") return WMethod::kLinearlyImplicitEuler;
  if (name == "rosenbrock") return WMethod::kRos2;
  return std::nullopt;
}

}  // namespace cpgait
