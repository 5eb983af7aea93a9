#pragma once
// Explicit Runge-Kutta 5(4) of Dormand & Prince (1980) with the embedded 4th-order error estimate,
// FSAL, and Hairer's PI step-size control (Hairer, Norsett & Wanner, "Solving ODEs I", II.4).
//
// Why explicit: OpenSim's own default (Runge-Kutta-Merson) is explicit too. With rigid tendons the
// fastest muscle dynamics are activation (tau >= ~7 ms) and foot contact (k = 1e6 N/m^1.5 under a
// ~1 kg foot: ~400 rad/s); both are resolved by steps of ~1 ms, which accuracy asks for anyway, and
// the error control shortens steps through impacts. A compliant tendon is stiffer; the controller
// shrinks the step until the stiff mode is stable (slow but correct) and the summary says how many
// steps it took, so a stiff run shows up in the numbers rather than as a wrong answer.
#include <Eigen/Core>
#include <functional>
#include <string>

namespace cpgait {

struct DormandPrinceOptions {
  double relative_tolerance = 1e-6;  // OpenSim's integrator_error_tolerance default in CMC setups
  double absolute_tolerance = 1e-6;
  double initial_step_s = 1e-3;
  double min_step_s = 1e-9;  // below this the integration fails (a singular or exploding model)
  double max_step_s = 0.01;
  long max_steps = 1000000;
};

struct DormandPrinceSummary {
  long accepted_steps = 0;
  long rejected_steps = 0;
  long evaluations = 0;
  double last_step_s = 0;  // carry into the next call to keep the step size between calls
  bool success = true;
  std::string message;
};

// dx/dt = f(t, x). Integrates x from t0 to t1 in place. f must not keep references to its arguments.
using OdeFunction = std::function<void(double t, const Eigen::VectorXd& x, Eigen::VectorXd& dxdt)>;
DormandPrinceSummary integrate_dormand_prince(const OdeFunction& f, double t0, double t1, Eigen::VectorXd& x,
                                              const DormandPrinceOptions& options = {});

// Shared by the integrators' step control (rosenbrock_w.h too):
// Before a step from t: false (with the summary's message) past max_steps; the step is clipped to
// end exactly at t1, and `last` says so.
bool begin_step(double t, double t1, long max_steps, double& h, bool& last, DormandPrinceSummary& s);
// RMS over the states of err_i / (atol + rtol max(|x_i|, |x_new_i|)); a non-finite error counts as huge.
double scaled_rms_error(const Eigen::VectorXd& err, const Eigen::VectorXd& x, const Eigen::VectorXd& x_new,
                        double relative_tolerance, double absolute_tolerance);
// After an accepted step: the next step (or, after the last step of the call, the one to start the
// next call with: never the clipped last step itself).
void next_step_after_accept(double& h, double factor, bool last, double h_unclipped, double max_step_s,
                            DormandPrinceSummary& s);
// After a rejected step: shrink by factor; false (with the summary's message) below min_step_s.
bool next_step_after_reject(double& h, double factor, double min_step_s, double t, DormandPrinceSummary& s);

}  // namespace cpgait
