#pragma once
// ROS2, the two-stage Rosenbrock W-method of Verwer, Spee, Blom & Hundsdorfer (1999), with an
// embedded first-order error estimate and step-size control. Each stage solves
//   (I - gamma h J) k = rhs,   gamma = 1 + 1/sqrt(2),
// with J any approximation of df/dx: as a W-method it keeps order two whatever J is, while the
// stiff parts that J does capture are integrated L-stably, so their time constants no longer bound
// the step. The caller supplies J through `prepare` (called once per step at its start) and the
// stage solve, so a model can exploit its structure instead of forming and factoring a dense matrix.
//
// Why for muscles: a compliant Thelen tendon's fibre equation has rate constants up to ~1e4 /s at
// low activation; an explicit method must then step at ~0.2 ms (measured with Dormand-Prince on
// gait2392). The fibre equations are per muscle (a diagonal Jacobian), so a W-method that treats
// them implicitly costs almost nothing per step.
#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "cpgait/dynamics/dormand_prince.h"

namespace cpgait {

struct RosenbrockOptions {
  double relative_tolerance = 1e-4;
  double absolute_tolerance = 1e-4;
  double initial_step_s = 1e-3;
  double min_step_s = 1e-9;
  double max_step_s = 0.01;
  long max_steps = 1000000;
};

// prepare(t, x, f0): build the Jacobian approximation at the step's start and f0 = f(t, x).
// solve(gamma_h, rhs, k): k = (I - gamma_h J)^-1 rhs with the prepared J.
using WPrepare = std::function<void(double t, const Eigen::VectorXd& x, Eigen::VectorXd& f0)>;
using WSolve = std::function<void(double gamma_h, const Eigen::VectorXd& rhs, Eigen::VectorXd& k)>;

// step_done(t_a, x_a, t_b, x_b): called after each accepted step from t_a to t_b, before the next
// one begins (a caller's dense output: states between steps, without cutting the steps there).
using WStepDone = std::function<void(double t_a, const Eigen::VectorXd& x_a, double t_b, const Eigen::VectorXd& x_b)>;

// Same summary as the explicit integrator (evaluations counts f only).
DormandPrinceSummary integrate_ros2(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                    double t1, Eigen::VectorXd& x, const RosenbrockOptions& options = {},
                                    const WStepDone& step_done = {});

// ROS34PW2 (Rang & Angermann 2005): four stages, order three with any J (a W-method), L-stable with
// the exact one, and an embedded second-order estimate: its steps grow as tol^(1/3) where ROS2's
// grow as tol^(1/2). Same interface; each step costs four evaluations and solves.
DormandPrinceSummary integrate_ros34pw2(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                        double t1, Eigen::VectorXd& x, const RosenbrockOptions& options = {},
                                        const WStepDone& step_done = {});

// The linearly implicit Euler method (Rosenbrock-Euler, Hairer & Wanner IV.7): x_new = x + h (I - h J)^-1
// f(t, x). First order with any J, L-stable with the exact one; one evaluation (prepare's) and one
// solve per step. It has no error estimate: it takes equal steps of at most max_step_s, ending at t1
// (the tolerances are unused). f is not called.
DormandPrinceSummary integrate_linearly_implicit_euler(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                                       double t1, Eigen::VectorXd& x, const RosenbrockOptions& options = {},
                                                       const WStepDone& step_done = {});

// The W-method a caller chose, and its integration.
enum class WMethod { kRos2, kRos34pw2, kLinearlyImplicitEuler };
// Their names in options and files: "rosenbrock" (ROS2), "ros34pw2" and "linearly_implicit_euler";
// nullopt for another name.
std::string w_method_name(WMethod method);
// The method a walk "at a tolerance" takes: the method itself, or ROS34PW2 for the linearly implicit
// Euler method, which has no tolerance (the gait's tolerance checks and tuning tolerances).
WMethod at_tolerance(WMethod method);
std::optional<WMethod> w_method_named(std::string_view name);
DormandPrinceSummary integrate_w_method(WMethod method, const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                        double t1, Eigen::VectorXd& x, const RosenbrockOptions& options = {},
                                        const WStepDone& step_done = {});

}  // namespace cpgait
