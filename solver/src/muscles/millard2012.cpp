#include "cpgait/muscles/millard2012.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "cpgait/muscles/fiber_equilibrium.h"

namespace cpgait::millard2012 {
namespace {

double scale_curviness(double c) { return 0.1 + 0.8 * c; }

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

// OpenSim's damping coefficient below which the model is the undamped one.
constexpr double kMinNonzeroDamping = 0.001;

}  // namespace

SmoothSegmentedFunction fiber_active_force_length_curve(const ActiveForceLengthParameters& p) {
  const double x0 = p.min_norm_active_fiber_length, x1 = p.transition_norm_fiber_length, x2 = 1.0,
               x3 = p.max_norm_active_fiber_length, ylow = p.minimum_value, dydx = p.shallow_ascending_slope;
  const double root_eps = std::sqrt(std::numeric_limits<double>::epsilon());
  require(x0 >= 0 && x1 > x0 + root_eps && x2 > x1 + root_eps && x3 > x2 + root_eps,
          "ActiveForceLengthCurve: 0 <= min_norm_active_fiber_length < transition_norm_fiber_length < 1 < "
          "max_norm_active_fiber_length must hold");
  require(ylow >= 0, "ActiveForceLengthCurve: minimum_value must be >= 0");
  require(dydx >= 0 && dydx < (1 - ylow) / (x2 - x1),
          "ActiveForceLengthCurve: shallow_ascending_slope must be >= 0 and < (1 - minimum_value) / (1 - "
          "transition_norm_fiber_length)");
  const double c = scale_curviness(1.0);
  // The plateau's half width is 5 % of the optimal length; the shallow ascending limb meets it there.
  const double x_delta = 0.05 * x2, xs = x2 - x_delta;
  const double y0 = 0, dydx0 = 0, y1 = 1 - dydx * (xs - x1);
  const double dydx01 = 1.25 * (y1 - y0) / (x1 - x0);
  const double x01 = x0 + 0.5 * (x1 - x0), y01 = y0 + 0.5 * (y1 - y0);
  const double x1s = x1 + 0.5 * (xs - x1), y1s = y1 + 0.5 * (1 - y1), dydx1s = dydx;
  const double y2 = 1, dydx2 = 0, y3 = 0, dydx3 = 0;
  const double x23 = (x2 + x_delta) + 0.5 * (x3 - (x2 + x_delta)), y23 = y2 + 0.5 * (y3 - y2);
  const double dydx23 = (y3 - y2) / ((x3 - x_delta) - (x2 + x_delta));
  std::vector<QuinticBezier> s = {
      quintic_bezier_corner(x0, ylow, dydx0, x01, y01, dydx01, c),
      quintic_bezier_corner(x01, y01, dydx01, x1s, y1s, dydx1s, c),
      quintic_bezier_corner(x1s, y1s, dydx1s, x2, y2, dydx2, c),
      quintic_bezier_corner(x2, y2, dydx2, x23, y23, dydx23, c),
      quintic_bezier_corner(x23, y23, dydx23, x3, ylow, dydx3, c)};
  return SmoothSegmentedFunction(std::move(s), x0, x3, ylow, ylow, 0, 0);
}

SmoothSegmentedFunction fiber_force_velocity_curve(const ForceVelocityParameters& p) {
  const double fmax = p.max_eccentric_velocity_force_multiplier, dydxC = p.concentric_slope_at_vmax,
               dydxNearC = p.concentric_slope_near_vmax, dydxIso = p.isometric_slope,
               dydxE = p.eccentric_slope_at_vmax, dydxNearE = p.eccentric_slope_near_vmax;
  require(fmax > 1, "ForceVelocityCurve: max_eccentric_velocity_force_multiplier must be > 1");
  require(dydxC >= 0 && dydxC < 1, "ForceVelocityCurve: concentric_slope_at_vmax must be in [0, 1)");
  require(dydxNearC > dydxC && dydxNearC <= 1,
          "ForceVelocityCurve: concentric_slope_near_vmax must be > concentric_slope_at_vmax and <= 1");
  require(dydxIso > 1, "ForceVelocityCurve: isometric_slope must be > 1");
  require(dydxE >= 0 && dydxE < fmax - 1,
          "ForceVelocityCurve: eccentric_slope_at_vmax must be >= 0 and < max_eccentric_velocity_force_multiplier - 1");
  require(dydxNearE >= dydxE && dydxNearE < fmax - 1,
          "ForceVelocityCurve: eccentric_slope_near_vmax must be >= eccentric_slope_at_vmax and < "
          "max_eccentric_velocity_force_multiplier - 1");
  require(p.concentric_curviness >= 0 && p.concentric_curviness <= 1,
          "ForceVelocityCurve: concentric_curviness must be in [0, 1]");
  require(p.eccentric_curviness >= 0 && p.eccentric_curviness <= 1,
          "ForceVelocityCurve: eccentric_curviness must be in [0, 1]");
  const double cC = scale_curviness(p.concentric_curviness), cE = scale_curviness(p.eccentric_curviness);
  const double xC = -1, yC = 0, xNearC = -0.9;
  const double yNearC = yC + 0.5 * dydxNearC * (xNearC - xC) + 0.5 * dydxC * (xNearC - xC);
  const double xIso = 0, yIso = 1, xE = 1, yE = fmax, xNearE = 0.9;
  const double yNearE = yE + 0.5 * dydxNearE * (xNearE - xE) + 0.5 * dydxE * (xNearE - xE);
  std::vector<QuinticBezier> s = {
      quintic_bezier_corner(xC, yC, dydxC, xNearC, yNearC, dydxNearC, cC),
      quintic_bezier_corner(xNearC, yNearC, dydxNearC, xIso, yIso, dydxIso, cC),
      quintic_bezier_corner(xIso, yIso, dydxIso, xNearE, yNearE, dydxNearE, cE),
      quintic_bezier_corner(xNearE, yNearE, dydxNearE, xE, yE, dydxE, cE)};
  return SmoothSegmentedFunction(std::move(s), xC, xE, yC, yE, dydxC, dydxE);
}

SmoothSegmentedFunction fiber_force_length_curve(const FiberForceLengthParameters& p) {
  const double e0 = p.strain_at_zero_force, e1 = p.strain_at_one_norm_force;
  const int given = p.stiffness_at_low_force.has_value() + p.stiffness_at_one_norm_force.has_value() + p.curviness.has_value();
  require(given == 0 || given == 3,
          "FiberForceLengthCurve: stiffness_at_low_force, stiffness_at_one_norm_force and curviness must all be "
          "given or all be absent");
  require(e1 > e0, "FiberForceLengthCurve: strain_at_one_norm_force must be > strain_at_zero_force");
  // Absent: OpenSim's fitted curve.
  const double k_iso = given ? *p.stiffness_at_one_norm_force : 2.0 / (e1 - e0);
  const double k_low = given ? *p.stiffness_at_low_force : 0.2;
  const double curviness = given ? *p.curviness : 0.75;
  require(k_iso > 1.0 / (e1 - e0),
          "FiberForceLengthCurve: stiffness_at_one_norm_force must be > 1 / (strain_at_one_norm_force - "
          "strain_at_zero_force)");
  require(k_low > 0 && k_low < 1 / (e1 - e0),
          "FiberForceLengthCurve: stiffness_at_low_force must be > 0 and < 1 / (strain_at_one_norm_force - "
          "strain_at_zero_force)");
  require(curviness >= 0 && curviness <= 1, "FiberForceLengthCurve: curviness must be in [0, 1]");
  const double c = scale_curviness(curviness);
  const double x_zero = 1 + e0, y_zero = 0, x_iso = 1 + e1, y_iso = 1;
  const double delta_x = std::min(0.1 * (1.0 / k_iso), 0.1 * (x_iso - x_zero));
  const double x_low = x_zero + delta_x, x_foot = x_zero + 0.5 * (x_low - x_zero), y_foot = 0;
  const double y_low = y_foot + k_low * (x_low - x_foot);
  std::vector<QuinticBezier> s = {quintic_bezier_corner(x_zero, y_zero, 0, x_low, y_low, k_low, c),
                                  quintic_bezier_corner(x_low, y_low, k_low, x_iso, y_iso, k_iso, c)};
  return SmoothSegmentedFunction(std::move(s), x_zero, x_iso, y_zero, y_iso, 0.0, k_iso);
}

SmoothSegmentedFunction tendon_force_length_curve(const TendonForceLengthParameters& p) {
  const double e_iso = p.strain_at_one_norm_force;
  const int given = p.stiffness_at_one_norm_force.has_value() + p.norm_force_at_toe_end.has_value() + p.curviness.has_value();
  require(given == 0 || given == 3,
          "TendonForceLengthCurve: stiffness_at_one_norm_force, norm_force_at_toe_end and curviness must all be "
          "given or all be absent");
  require(e_iso > 0, "TendonForceLengthCurve: strain_at_one_norm_force must be > 0");
  const double k_iso = given ? *p.stiffness_at_one_norm_force : 1.375 / e_iso;
  const double f_toe = given ? *p.norm_force_at_toe_end : 2.0 / 3.0;
  const double curviness = given ? *p.curviness : 0.5;
  require(f_toe > 0 && f_toe < 1, "TendonForceLengthCurve: norm_force_at_toe_end must be in (0, 1)");
  require(k_iso > 1 / e_iso, "TendonForceLengthCurve: stiffness_at_one_norm_force must be > 1 / strain_at_one_norm_force");
  require(curviness >= 0 && curviness <= 1, "TendonForceLengthCurve: curviness must be in [0, 1]");
  const double c = scale_curviness(curviness);
  const double x0 = 1.0, y0 = 0, dydx0 = 0, x_iso = 1.0 + e_iso, y_iso = 1;
  const double y_toe = f_toe, x_toe = (y_toe - 1) / k_iso + x_iso;
  const double x_foot = 1.0 + (x_toe - 1.0) / 10.0, y_foot = 0;
  const double y_toe_mid = 0.5 * y_toe, x_toe_mid = (y_toe_mid - y_iso) / k_iso + x_iso;
  const double dydx_toe_mid = (y_toe_mid - y_foot) / (x_toe_mid - x_foot);
  const double x_toe_ctrl = x_foot + 0.5 * (x_toe_mid - x_foot);
  const double y_toe_ctrl = y_foot + dydx_toe_mid * (x_toe_ctrl - x_foot);
  std::vector<QuinticBezier> s = {quintic_bezier_corner(x0, y0, dydx0, x_toe_ctrl, y_toe_ctrl, dydx_toe_mid, c),
                                  quintic_bezier_corner(x_toe_ctrl, y_toe_ctrl, dydx_toe_mid, x_toe, y_toe, k_iso, c)};
  return SmoothSegmentedFunction(std::move(s), x0, x_toe, y0, y_toe, dydx0, k_iso);
}

Curves make_curves(const Parameters& p) {
  Curves c;
  c.parameters = p;
  c.use_fiber_damping = p.fiber_damping >= kMinNonzeroDamping;
  c.sin_max_pennation = std::sin(p.maximum_pennation_angle_rad);
  c.cos_max_pennation = std::cos(p.maximum_pennation_angle_rad);
  if (!c.use_fiber_damping) c.parameters.fiber_damping = 0.0;
  ActiveForceLengthParameters fal = p.active_force_length;
  ForceVelocityParameters fv = p.force_velocity;
  if (!p.ignore_tendon_compliance && !c.use_fiber_damping) {
    require(p.minimum_activation >= 0.01, "minimum_activation cannot be less than 0.01 with an undamped elastic tendon");
    fal.minimum_value = std::max(fal.minimum_value, 0.1);
    if (fv.concentric_slope_at_vmax < 0.1 || fv.eccentric_slope_at_vmax < 0.1) {
      fv.concentric_slope_at_vmax = 0.1;
      fv.eccentric_slope_at_vmax = 0.1;
    }
  } else {
    require(p.minimum_activation >= 0, "minimum_activation cannot be less than zero");
    c.parameters.minimum_activation = std::clamp(p.minimum_activation, 0.0, 1.0);
    fal.minimum_value = 0.0;
    fv.concentric_slope_at_vmax = 0.0;
    fv.eccentric_slope_at_vmax = 0.0;
  }
  c.parameters.active_force_length = fal;
  c.parameters.force_velocity = fv;
  c.active_force_length = fiber_active_force_length_curve(fal);
  c.force_velocity = fiber_force_velocity_curve(fv);
  {
    // OpenSim's fvInvCurve: the same corners with x and y swapped, end slopes kept at 0.1 or more.
    ForceVelocityParameters inv = fv;
    if (inv.concentric_slope_at_vmax < 0.1 || inv.eccentric_slope_at_vmax < 0.1)
      inv.concentric_slope_at_vmax = inv.eccentric_slope_at_vmax = 0.1;
    const SmoothSegmentedFunction f = fiber_force_velocity_curve(inv);
    std::vector<QuinticBezier> swapped;
    for (const auto& seg : f.segments()) swapped.push_back({seg.y, seg.x});
    c.force_velocity_inverse = SmoothSegmentedFunction(std::move(swapped), 0.0, inv.max_eccentric_velocity_force_multiplier,
                                                       -1.0, 1.0, 1.0 / inv.concentric_slope_at_vmax,
                                                       1.0 / inv.eccentric_slope_at_vmax);
  }
  c.fiber_force_length = fiber_force_length_curve(p.fiber_force_length);
  c.tendon_force_length = tendon_force_length_curve(p.tendon_force_length);
  return c;
}

namespace {

// OpenSim's MuscleFixedWidthPennationModel with the muscle's maximum pennation angle.
struct FixedWidthPennation {
  double height, max_sin, max_cos, max_angle, min_fiber_length, min_fiber_length_along_tendon;
  bool pennated;
  // The maximum angle's sine and cosine come with the curves: this is built in every evaluation.
  FixedWidthPennation(const Muscle& m, const Curves& c)
      : height(m.optimal_fiber_length_m * m.sin_pennation_at_optimal),
        max_sin(c.sin_max_pennation),
        max_cos(c.cos_max_pennation),
        max_angle(c.parameters.maximum_pennation_angle_rad),
        min_fiber_length(max_angle > 1e-14 ? height / max_sin : 0.01 * m.optimal_fiber_length_m),
        min_fiber_length_along_tendon(min_fiber_length * max_cos),
        pennated(m.pennation_angle_at_optimal_rad > std::numeric_limits<double>::epsilon()) {}
  double angle(double fiber_length) const {
    if (!pennated) return 0.0;
    if (fiber_length <= min_fiber_length) return max_angle;
    const double s = height / fiber_length;
    return s < max_sin ? std::asin(s) : max_angle;
  }
  double cos_angle(double fiber_length) const {  // cos(angle(fiber_length)), without a cos or an asin
    if (!pennated) return 1.0;
    if (fiber_length <= min_fiber_length) return max_cos;
    const double s = height / fiber_length;
    return s < max_sin ? std::sqrt(1.0 - s * s) : max_cos;
  }
  double fiber_length(double path_length, double tendon_length) const {
    const double along = path_length - tendon_length;
    return along >= min_fiber_length_along_tendon ? std::sqrt(height * height + along * along) : min_fiber_length;
  }
};

// Millard's fibre length floor (OpenSim's m_minimumFiberLength).
double shortest_fiber(const Muscle& m, const Curves& c, const FixedWidthPennation& pen) {
  return std::max(1e-14, std::max(c.parameters.active_force_length.min_norm_active_fiber_length * m.optimal_fiber_length_m,
                                  pen.min_fiber_length));
}

// OpenSim's calcDampedNormFiberVelocity: the normalised fibre velocity at which the damped fibre's
// force along the tendon equals the tendon's; Newton from `guess`, or where that is NaN from the
// inverse force-velocity curve's.
// The residual rises strictly with the velocity (fv' >= 0, damping > 0), so the root is unique.
double damped_norm_fiber_velocity(const Curves& c, double a, double fal, double fpe, double fse, double cos_pen, double guess) {
  const double beta = c.parameters.fiber_damping;
  double v = guess;
  if (!std::isfinite(v)) {
    const double fv_guess = (fse / std::max(cos_pen, 0.01) - fpe) / (std::max(a, 0.01) * std::max(fal, 0.01));
    v = std::clamp(c.force_velocity_inverse.value(fv_guess), -1.0, 1.0);
  }
  // Newton within the bracket the residual's signs have set so far, bisecting where a step would
  // leave it: across fv's corner at isometric a plain Newton step can cycle between the eccentric
  // and concentric sides (from v = 0.14 it jumped between -1.14 and 0.78 for good).
  double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 100; ++it) {
    double fv, dfv;
    c.force_velocity.value_and_derivative(v, fv, dfv);
    const double err = (a * fal * fv + fpe + beta * v) * cos_pen - fse;
    if (std::abs(err) <= 1e-10) break;  // OpenSim's tolerance, 1e-10 max isometric force
    (err > 0 ? hi : lo) = v;
    double next = v - err / ((a * fal * dfv + beta) * cos_pen);
    if (std::isfinite(lo) && std::isfinite(hi) && !(next > lo && next < hi)) {
      next = 0.5 * (lo + hi);
    } else if (std::abs(next - v) <= 1e-6) {
      return next;  // Newton converges quadratically: the step after would be ~1e-12 (saves an evaluation)
    }
    if (next == v) break;
    v = next;
  }
  return v;
}

}  // namespace

double min_fiber_length(const Muscle& m) {
  const Curves& c = *m.millard;
  return shortest_fiber(m, c, FixedWidthPennation(m, c));
}

double rigid_tendon_fiber_length(const Muscle& m, double L) {
  const Curves& c = *m.millard;
  const FixedWidthPennation pen(m, c);
  return std::max(pen.fiber_length(L, m.tendon_slack_length_m), shortest_fiber(m, c, pen));
}

RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double L, double V) {
  const Curves& c = *m.millard;
  const FixedWidthPennation pen(m, c);
  const double lmin = shortest_fiber(m, c, pen);
  const double lce = rigid_tendon_fiber_length(m, L);
  const double cos_pen = pen.cos_angle(lce);
  double vN = 0.0, fv = 1.0;
  // A slack tendon buckles: the fibre does not move with the path.
  if (L - lce * cos_pen >= m.tendon_slack_length_m - 1e-14) {
    vN = V * cos_pen / (m.optimal_fiber_length_m * m.max_contraction_velocity);
    fv = c.force_velocity.value(vN);
  }
  if ((lce <= lmin && vN <= 0) || lce < lmin) vN = 0.0, fv = 1.0;  // held at its shortest
  const double a = std::clamp(activation, c.parameters.minimum_activation, 1.0);
  const double lN = lce / m.optimal_fiber_length_m;
  const double active = a * c.active_force_length.value(lN) * fv;
  double passive = c.fiber_force_length.value(lN) + c.parameters.fiber_damping * vN;
  if (active + passive < 0) passive = -active;  // a rigid tendon cannot push
  return {m.max_isometric_force_N * active * cos_pen, m.max_isometric_force_N * passive * cos_pen};
}

CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double L, double lm, double velocity_guess_m_s) {
  const Curves& c = *m.millard;
  const FixedWidthPennation pen(m, c);
  const double lmin = shortest_fiber(m, c, pen);
  lm = std::max(lm, lmin);
  const double cos_pen = pen.cos_angle(lm);
  const double fse = c.tendon_force_length.value((L - lm * cos_pen) / m.tendon_slack_length_m);
  const double a = std::clamp(activation, c.parameters.minimum_activation, 1.0);
  const double lN = lm / m.optimal_fiber_length_m;
  const double fal = c.active_force_length.value(lN), fpe = c.fiber_force_length.value(lN);
  const double guess = std::clamp(velocity_guess_m_s / (m.optimal_fiber_length_m * m.max_contraction_velocity), -1.0, 1.0);
  double vN = c.use_fiber_damping ? damped_norm_fiber_velocity(c, a, fal, fpe, fse, cos_pen, guess)
                                  : c.force_velocity_inverse.value((fse / cos_pen - fpe) / (a * fal));
  if (lm <= lmin && vN <= 0) vN = 0.0;
  return {m.max_isometric_force_N * fse, vN * m.optimal_fiber_length_m * m.max_contraction_velocity, cos_pen};
}

std::optional<CompliantTendonFiber> implicit_fiber_step(const Muscle& m, double activation, double L, double base_m,
                                                       double step_s, double& lm, double& v_m_s) {
  const Curves& c = *m.millard;
  if (!c.use_fiber_damping) return std::nullopt;
  const FixedWidthPennation pen(m, c);
  const double lmin = shortest_fiber(m, c, pen);
  const double lopt = m.optimal_fiber_length_m, K = lopt * m.max_contraction_velocity, Lts = m.tendon_slack_length_m;
  const double a = std::clamp(activation, c.parameters.minimum_activation, 1.0), beta = c.parameters.fiber_damping;
  const double chK = step_s * K;
  // On the step's line l = base + step v the force balance R(v) rises with the velocity (damping and
  // the tendon's stiffness): Newton in v within the bracket its signs have set, bisecting where a step
  // would leave it (as damped_norm_fiber_velocity, whose start this is).
  double v = v_m_s / K;  // normalised, as the curves take it
  double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 60; ++it) {
    const double l = base_m + chK * v;
    // Near the floor the fibre's velocity is held (compliant_tendon_fiber's corner): left to the caller.
    if (!(l > 1.01 * lmin) || !std::isfinite(v)) return std::nullopt;
    double cos_pen = 1, dcos_dl = 0;
    if (pen.pennated) {
      const double sn = pen.height / l;
      if (!(sn < pen.max_sin)) return std::nullopt;
      cos_pen = std::sqrt(1.0 - sn * sn);
      dcos_dl = sn * sn / (l * cos_pen);
    }
    double fal, dfal, fpe, dfpe, fse, dfse, fv, dfv;
    c.active_force_length.value_and_derivative(l / lopt, fal, dfal);
    c.fiber_force_length.value_and_derivative(l / lopt, fpe, dfpe);
    c.tendon_force_length.value_and_derivative((L - l * cos_pen) / Lts, fse, dfse);
    c.force_velocity.value_and_derivative(v, fv, dfv);
    const double fibre = a * fal * fv + fpe + beta * v;
    const double R = fibre * cos_pen - fse;  // force balance along the tendon, normalised
    const double R_l = (a * dfal * fv + dfpe) / lopt * cos_pen + fibre * dcos_dl + dfse / (cos_pen * Lts);  // d(l cos)/dl = 1/cos
    const double dR_dv = (a * fal * dfv + beta) * cos_pen + chK * R_l;
    (R > 0 ? hi : lo) = v;
    const double dv = dR_dv > 0 ? -R / dR_dv : std::numeric_limits<double>::quiet_NaN();
    // Within 1e-7 of the root (force and length, normalised) Newton's next iterate is within ~1e-14
    // (the error squares on these C2 curves): it is returned, its tendon force by the same linear step.
    if (std::abs(R) <= 1e-7 && std::abs(chK * dv) <= 1e-7 * lopt) {
      const double dl = chK * dv;
      lm = l + dl;
      v_m_s = (v + dv) * K;
      return CompliantTendonFiber{m.max_isometric_force_N * (fse - dfse * dl / (cos_pen * Lts)), v_m_s, cos_pen};
    }
    double next = v + dv;
    if (!(next > lo && next < hi)) {
      if (!std::isfinite(lo) || !std::isfinite(hi)) return std::nullopt;  // leaving a side it has seen, unbracketed
      next = 0.5 * (lo + hi);
    }
    if (next == v) return std::nullopt;
    v = next;
  }
  return std::nullopt;
}

double compliant_equilibrium_fiber_length(const Muscle& m, double activation, double L, double V) {
  const Curves& c = *m.millard;
  const FixedWidthPennation pen(m, c);
  const double a = std::clamp(activation, c.parameters.minimum_activation, 1.0);
  auto residual = [&](double lm) {  // tendon minus fibre, normalised by max isometric force
    const double cos_pen = pen.cos_angle(lm);
    const double lN = lm / m.optimal_fiber_length_m;
    const double vN = V * cos_pen / (m.optimal_fiber_length_m * m.max_contraction_velocity);
    const double fibre = a * c.active_force_length.value(lN) * c.force_velocity.value(vN) + c.fiber_force_length.value(lN) +
                         c.parameters.fiber_damping * vN;
    return c.tendon_force_length.value((L - lm * cos_pen) / m.tendon_slack_length_m) - fibre * cos_pen;
  };
  const double lo = shortest_fiber(m, c, pen);
  const double hi = std::max(pen.fiber_length(L, m.tendon_slack_length_m), lo);
  return falling_root(residual, lo, hi, 1e-12);
}

double inextensible_tendon_active_force(const Muscle& m, double activation, double L, double V) {
  const Curves& c = *m.millard;
  const FixedWidthPennation pen(m, c);
  const double lce = pen.fiber_length(L, m.tendon_slack_length_m);
  const double dlce = V * pen.cos_angle(lce);
  if (lce <= shortest_fiber(m, c, pen)) return 0.0;
  const double a = std::clamp(activation, c.parameters.minimum_activation, 1.0);
  const double lceN = lce / m.optimal_fiber_length_m;
  const double dlceN = dlce / (m.optimal_fiber_length_m * m.max_contraction_velocity);
  return m.max_isometric_force_N * a * c.active_force_length.value(lceN) * c.force_velocity.value(dlceN) *
         std::cos(pen.angle(lceN));
}

}  // namespace cpgait::millard2012
