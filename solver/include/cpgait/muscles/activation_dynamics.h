#pragma once
// Thelen (2003) first-order activation dynamics, as OpenSim's Thelen2003Muscle:
//   da/dt = (u - a) / tau,  tau = tau_act (0.5 + 1.5 a) when u > a (activating),
//                           tau = tau_deact / (0.5 + 1.5 a) otherwise (deactivating),
// with the excitation u clamped to the muscle's [min_control, max_control].
#include "cpgait/model/model.h"

namespace cpgait {

double thelen_activation_rate(const Muscle& muscle, double excitation, double activation);

}  // namespace cpgait
