#pragma once
// OpenSim's Millard2012EquilibriumMuscle: Millard et al. (2013)'s curves as OpenSim builds them
// (SmoothSegmentedFunctionFactory, from each curve's properties and OpenSim's defaults), its
// fixed-width pennation, and the forces static optimization asks of it. Lengths normalised by
// optimal fibre length, velocities by optimal fibre length x max contraction velocity, forces by
// max isometric force.
#include <limits>
#include <optional>

#include "cpgait/model/model.h"
#include "cpgait/muscles/fiber_state.h"
#include "cpgait/muscles/smooth_segmented_function.h"

namespace cpgait::millard2012 {

// Each curve's OpenSim properties, with OpenSim's defaults.
struct ActiveForceLengthParameters {
  double min_norm_active_fiber_length = 0.47 - 0.0259;
  double transition_norm_fiber_length = 0.73;
  double max_norm_active_fiber_length = 1.8123;
  double shallow_ascending_slope = 0.8616;
  double minimum_value = 0.1;
  bool operator==(const ActiveForceLengthParameters&) const = default;
};
struct ForceVelocityParameters {
  double concentric_slope_at_vmax = 0.0;
  double concentric_slope_near_vmax = 0.25;
  double isometric_slope = 5.0;
  double eccentric_slope_at_vmax = 0.0;
  double eccentric_slope_near_vmax = 0.15;
  double max_eccentric_velocity_force_multiplier = 1.4;
  double concentric_curviness = 0.6;
  double eccentric_curviness = 0.9;
  bool operator==(const ForceVelocityParameters&) const = default;
};
// The optional properties are either all given or all absent (then OpenSim's fitted curve).
struct FiberForceLengthParameters {
  double strain_at_zero_force = 0.0;
  double strain_at_one_norm_force = 0.7;
  std::optional<double> stiffness_at_low_force, stiffness_at_one_norm_force, curviness;
  bool operator==(const FiberForceLengthParameters&) const = default;
};
struct TendonForceLengthParameters {
  double strain_at_one_norm_force = 0.049;
  std::optional<double> stiffness_at_one_norm_force, norm_force_at_toe_end, curviness;
  bool operator==(const TendonForceLengthParameters&) const = default;
};

struct Parameters {
  ActiveForceLengthParameters active_force_length;
  ForceVelocityParameters force_velocity;
  FiberForceLengthParameters fiber_force_length;
  TendonForceLengthParameters tendon_force_length;
  double fiber_damping = 0.1;            // normalised; below 1e-3 OpenSim switches to the undamped model
  double minimum_activation = 0.01;
  double maximum_pennation_angle_rad = 1.4706289056333368;  // acos(0.1)
  bool ignore_tendon_compliance = false;
  bool operator==(const Parameters&) const = default;
};

// The curves factory (OpenSim's SmoothSegmentedFunctionFactory). Each throws std::invalid_argument
// naming the property that breaks OpenSim's conditions.
SmoothSegmentedFunction fiber_active_force_length_curve(const ActiveForceLengthParameters& p);
SmoothSegmentedFunction fiber_force_velocity_curve(const ForceVelocityParameters& p);
SmoothSegmentedFunction fiber_force_length_curve(const FiberForceLengthParameters& p);
SmoothSegmentedFunction tendon_force_length_curve(const TendonForceLengthParameters& p);

// A muscle's curves as OpenSim's extendFinalizeFromProperties leaves them: with fibre damping or a
// rigid tendon the active-force-length minimum and the force-velocity end slopes are set to zero
// (the singularity-free model); an undamped elastic tendon keeps them at least 0.1.
struct Curves {
  Parameters parameters;
  SmoothSegmentedFunction active_force_length, force_velocity, fiber_force_length, tendon_force_length;
  // The inverse of a force-velocity curve with end slopes of at least 0.1 (OpenSim's fvInvCurve):
  // exact for the undamped model, the damped one's starting guess.
  SmoothSegmentedFunction force_velocity_inverse;
  bool use_fiber_damping = true;
  double sin_max_pennation = 0, cos_max_pennation = 1;  // of parameters.maximum_pennation_angle_rad
};
Curves make_curves(const Parameters& p);

// OpenSim's calcInextensibleTendonActiveFiberForce: the active fibre force along the tendon (N) with
// the tendon at its slack length, static optimization's force at activation a. It reproduces
// OpenSim 4's evaluation of the pennation angle at the normalised fibre length (a dimensional slip
// that makes cos(pennation) ~1 for every fibre), so that static optimization matches OpenSim's.
double inextensible_tendon_active_force(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

// The shortest fibre: where the active force-length curve ends or pennation reaches its maximum.
double min_fiber_length(const Muscle& m);

// Rigid tendon (OpenSim's ignore_tendon_compliance): active a*fal*fv and passive fpe + damping*v,
// along the tendon.
RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);
double rigid_tendon_fiber_length(const Muscle& m, double path_length_m);

// Elastic tendon at fibre length lm: the tendon force and the fibre velocity that balances it
// (OpenSim's calcFiberVelocityInfo: Newton on the damped equilibrium, or the inverse force-velocity
// curve without damping); the fibre is held at its minimum length while it would shorten there.
// velocity_guess_m_s: where the damped Newton starts (a nearby evaluation's velocity: 1-2 steps
// instead of 3-4 from the inverse curve's guess); NaN: from that guess.
CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double path_length_m, double fiber_length_m,
                                            double velocity_guess_m_s = std::numeric_limits<double>::quiet_NaN());

// One implicit step of the damped fibre: the velocity v (m/s) and length lm = base_m + step_s v at
// which the fibre carries the tendon's force at path length L, by Newton in v with the length on the
// step's line (compliant_tendon_fiber solves the velocity for a given length; a step solved around it
// nests one Newton in another). v_m_s in: the start; out: the root. lm out: the root's length. The
// fibre there, or empty (lm, v_m_s unchanged) without fibre damping, near the fibre's shortest length
// or unbracketed: the caller's own solve then.
std::optional<CompliantTendonFiber> implicit_fiber_step(const Muscle& m, double activation, double path_length_m, double base_m,
                                                       double step_s, double& lm, double& v_m_s);

// The fibre length where tendon and fibre forces balance with the fibre moving at the path's speed
// along it (bisection: the residual falls as the fibre lengthens).
double compliant_equilibrium_fiber_length(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

}  // namespace cpgait::millard2012
