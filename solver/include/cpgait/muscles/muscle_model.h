#pragma once
// A muscle's forces by its own model: OpenSim's Millard2012EquilibriumMuscle (millard2012.h),
// DeGrooteFregly2016Muscle, RigidTendonMuscle and Schutte1993Muscle (schutte1993.h) for the muscles
// that are one, Thelen 2003 (thelen2003.h) for the others. The dynamics, CMC and the gait call these;
// the models' own functions stay specific.
#include <limits>

#include "cpgait/model/model.h"
#include "cpgait/muscles/fiber_state.h"

namespace cpgait::muscles {

// Whether the muscle's own model has an inextensible tendon (RigidTendonMuscle, or
// ignore_tendon_compliance): then it has no fibre state, even where the others' tendons are compliant.
bool has_rigid_tendon(const Muscle& m);

// Rigid tendon at path length L (m) and lengthening speed V (m/s).
RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);
double rigid_tendon_active_force(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);
double rigid_tendon_fiber_length(const Muscle& m, double path_length_m);
// Static optimization's force at this activation, as OpenSim's calcInextensibleTendonActiveFiberForce
// gives it for the muscle's own model (Millard's and the deprecated muscles' have their own; the
// others' is the rigid tendon's active force).
double inextensible_tendon_active_force(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

// Compliant tendon with the fibre length a state. velocity_guess_m_s: a nearby evaluation's fibre
// velocity, where a model that iterates for it starts (Millard's damped fibre); NaN: none.
CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double path_length_m, double fiber_length_m,
                                            double velocity_guess_m_s = std::numeric_limits<double>::quiet_NaN());

// The fibre length at which tendon and fibre forces balance with the fibre moving at the path's
// speed along it: a compliant muscle's initial state.
double compliant_equilibrium_fiber_length(const Muscle& m, double activation, double path_length_m,
                                          double path_speed_m_s);

// The fibre length at rest in isometric equilibrium at activation a: what OpenSim's
// equilibrateMuscles sets (Schutte1993Muscle by its own iteration).
double isometric_fiber_length(const Muscle& m, double activation, double path_length_m);

// What a caller of compliant_muscle_after knows at the start, shared by its calls from one state:
// the fibre velocity there (m/s; NaN: unknown) and the fibre velocity's slope against fibre length
// (1/s, <= 0; NaN: unknown, then found and stored by the first call).
struct PredictorStart {
  double fiber_velocity_m_s = std::numeric_limits<double>::quiet_NaN();
  double velocity_slope_per_s = std::numeric_limits<double>::quiet_NaN();
};

// A compliant muscle's state after `duration_s` of constant excitation while its path length moves
// linearly from L0 to L1: activation as thelen_activation_after steps it, fibre length by BDF2
// (the fibre equation is stiff at low activation: its rate constant reaches ~1e4 /s), substeps of at
// most 1.7 ms. CMC's force predictor. `start` (optional) saves the evaluations it holds.
CompliantMuscleState compliant_muscle_after(const Muscle& m, double activation, double fiber_length_m, double L0_m,
                                            double L1_m, double excitation, double duration_s,
                                            PredictorStart* start = nullptr);

}  // namespace cpgait::muscles
