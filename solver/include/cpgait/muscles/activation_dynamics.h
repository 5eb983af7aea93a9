#pragma once
// Thelen (2003) first-order activation dynamics, as OpenSim's Thelen2003Muscle (and its
// Millard2012EquilibriumMuscle, which also holds the activation to [minimum_activation, 1]):
//   da/dt = (u - a) / tau,  tau = tau_act (0.5 + 1.5 a) when u > a (activating),
//                           tau = tau_deact / (0.5 + 1.5 a) otherwise (deactivating),
// with the excitation u clamped to the muscle's [min_control, max_control].
#include "cpgait/model/model.h"

namespace cpgait {

double thelen_activation_rate(const Muscle& muscle, double excitation, double activation);

}  // namespace cpgait

namespace cpgait {

// Activation after `duration_s` of constant excitation from a0 (RK4 on 1 ms or finer substeps:
// the rate's time constant is at least 0.5 tau_act, ~7 ms for gait2392).
double thelen_activation_after(const Muscle& muscle, double a0, double excitation, double duration_s);

// The constant excitation in [u_min, u_max] whose activation after duration_s is closest to
// a_target (bisection: the end activation rises monotonically with the excitation).
double thelen_excitation_for(const Muscle& muscle, double a0, double a_target, double duration_s, double u_min,
                             double u_max);

}  // namespace cpgait
