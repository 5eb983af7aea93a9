#include "cpgait/muscles/muscle_model.h"

#include <algorithm>
#include <cmath>

#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/degroote_fregly2016.h"
#include "cpgait/muscles/millard2012.h"
#include "cpgait/muscles/rigid_tendon_muscle.h"
#include "cpgait/muscles/schutte1993.h"
#include "cpgait/muscles/thelen2003.h"

namespace cpgait::muscles {

bool has_rigid_tendon(const Muscle& m) {
  if (m.rigid_tendon) return true;
  if (m.degroote) return m.degroote->ignore_tendon_compliance;
  if (m.millard) return m.millard->parameters.ignore_tendon_compliance;
  return false;
}

RigidTendonForces rigid_tendon_forces(const Muscle& m, double a, double L, double V) {
  if (m.rigid_tendon) return rigid_tendon_muscle::forces(m, a, L, V);
  if (m.schutte) return schutte1993::rigid_tendon_forces(m, a, L, V);
  if (m.degroote) return degroote_fregly2016::rigid_tendon_forces(m, a, L, V);
  return m.millard ? millard2012::rigid_tendon_forces(m, a, L, V) : thelen2003::rigid_tendon_forces(m, a, L, V);
}

double rigid_tendon_active_force(const Muscle& m, double a, double L, double V) {
  if (m.rigid_tendon || m.degroote || m.millard || m.schutte) return rigid_tendon_forces(m, a, L, V).active_N;
  return thelen2003::rigid_tendon_active_force(m, a, L, V);
}

double inextensible_tendon_active_force(const Muscle& m, double a, double L, double V) {
  if (m.millard) return millard2012::inextensible_tendon_active_force(m, a, L, V);
  if (m.schutte) return schutte1993::inextensible_tendon_active_force(m, a, L, V);
  return rigid_tendon_active_force(m, a, L, V);
}

double rigid_tendon_fiber_length(const Muscle& m, double L) {
  if (m.rigid_tendon) return rigid_tendon_muscle::fiber_length(m, L);
  if (m.schutte) return schutte1993::rigid_tendon_fiber_length(m, L);
  if (m.degroote) return degroote_fregly2016::rigid_tendon_fiber_length(m, L);
  return m.millard ? millard2012::rigid_tendon_fiber_length(m, L) : thelen2003::rigid_tendon_fiber(m, L, 0.0).fiber_length_m;
}

CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double a, double L, double lm, double velocity_guess_m_s) {
  if (!m.millard && !m.degroote && !m.rigid_tendon && !m.schutte) return thelen2003::compliant_tendon_fiber(m, a, L, lm);  // most muscles
  if (m.schutte) return schutte1993::compliant_tendon_fiber(m, a, L, lm);
  if (has_rigid_tendon(m)) {  // no fibre state: the force at rest, the fibre held on the path
    const RigidTendonForces f = rigid_tendon_forces(m, a, L, 0.0);
    return {f.active_N + f.passive_N, 0.0, 1.0};
  }
  if (m.degroote) return degroote_fregly2016::compliant_tendon_fiber(m, a, L, lm);
  return m.millard ? millard2012::compliant_tendon_fiber(m, a, L, lm, velocity_guess_m_s) : thelen2003::compliant_tendon_fiber(m, a, L, lm);
}

double compliant_equilibrium_fiber_length(const Muscle& m, double a, double L, double V) {
  if (has_rigid_tendon(m)) return rigid_tendon_fiber_length(m, L);
  // OpenSim's computeInitialFiberEquilibrium for this muscle is its isometric equilibrium.
  if (m.schutte) return schutte1993::isometric_equilibrium(m, a, L).fiber_length_m;
  if (m.degroote) return degroote_fregly2016::compliant_equilibrium_fiber_length(m, a, L, V);
  return m.millard ? millard2012::compliant_equilibrium_fiber_length(m, a, L, V)
                   : thelen2003::compliant_equilibrium_fiber_length(m, a, L, V);
}

double isometric_fiber_length(const Muscle& m, double a, double L) {
  return m.schutte ? schutte1993::isometric_equilibrium(m, a, L).fiber_length_m : compliant_equilibrium_fiber_length(m, a, L, 0.0);
}

CompliantMuscleState compliant_muscle_after(const Muscle& m, double a, double lm, double L0, double L1, double u, double T,
                                            PredictorStart* start) {
  const int n = std::max(1, static_cast<int>(std::ceil(T / 1.7e-3 - 1e-9)));
  const double h = T / n;
  if (has_rigid_tendon(m)) {
    a = thelen_activation_after(m, a, u, T);
    const RigidTendonForces f = rigid_tendon_forces(m, a, L1, (L1 - L0) / T);
    return {a, rigid_tendon_fiber_length(m, L1), f.active_N + f.passive_N};
  }
  const double lm_min = m.millard   ? millard2012::min_fiber_length(m)
                        : m.schutte ? schutte1993::min_fiber_length(m)
                                    : thelen2003::min_fiber_length(m);
  // CMC's tracking depends on this: stopping at 1e-9 of the optimal length on g doubled subject01's
  // pelvis and lumbar errors (0.22 -> 0.45 deg pelvis_list); from 1e-11 down they no longer change.
  const double tol = 1e-11 * m.optimal_fiber_length_m;
  // BDF2 (backward Euler on the first substep): g(l) = l - base - c h v(a, L, l) = 0, with base and
  // c = 1 (Euler) or (4 lm - lm_prev) / 3 and 2/3. g rises monotonically (v falls as the fibre
  // lengthens), so its slope is at least 1. Secant steps from an explicit start, the first slope
  // carried over from the previous substep (a finite difference on the first): one velocity
  // evaluation per iterate instead of Newton's two, in about as many iterates.
  // -dv/dl, the fibre velocity's response to its length (>= 0); < 0: unknown.
  double stiffness = start && start->velocity_slope_per_s <= 0 ? -start->velocity_slope_per_s : -1;
  double lm_prev = lm, v_prev = 0;
  CompliantTendonFiber at{};  // the fibre at the current iterate
  if (start && std::isfinite(start->fiber_velocity_m_s)) at.fiber_velocity_m_s = start->fiber_velocity_m_s;
  else at = compliant_tendon_fiber(m, a, L0, lm);
  for (int i = 1; i <= n; ++i) {
    a = thelen_activation_after(m, a, u, h);
    const double L = L0 + (L1 - L0) * i / n;
    const double base = i == 1 ? lm : (4 * lm - lm_prev) / 3, ch = i == 1 ? h : 2 * h / 3;
    // Start: the velocity extrapolated linearly from the last two substeps.
    const double v_start = i == 1 ? at.fiber_velocity_m_s : 2 * at.fiber_velocity_m_s - v_prev;
    v_prev = at.fiber_velocity_m_s;
    double l = std::max(base + ch * v_start, lm_min);
    if (m.millard) {  // length and velocity by one Newton (the secant below nests Millard's velocity solve)
      double v = v_start;
      if (const auto fibre = millard2012::implicit_fiber_step(m, a, L, base, ch, l, v)) {
        at = *fibre;
        lm_prev = lm;
        lm = l;
        continue;
      }
    }
    at = compliant_tendon_fiber(m, a, L, l, v_start);  // an iterating model's start: the velocity l was taken from
    double g = l - base - ch * at.fiber_velocity_m_s;
    if (stiffness < 0) {
      const double dl = 1e-7 * m.optimal_fiber_length_m;
      stiffness = std::max(0.0, -(compliant_tendon_fiber(m, a, L, l + dl, at.fiber_velocity_m_s).fiber_velocity_m_s - at.fiber_velocity_m_s) / dl);
      if (start) start->velocity_slope_per_s = -stiffness;
    }
    // |g| bounds the distance to the root (slope >= 1): the test is on g, not on the step, which a
    // secant through a kink of v (Thelen's force-velocity branches) can make small far from it.
    for (int k = 0; k < 40 && std::abs(g) >= tol; ++k) {
      const double l_next = std::max(l - g / (1 + ch * stiffness), lm_min);
      if (l_next == l) break;  // at the floor
      // The velocity guess moves with the slope the step was taken on (Millard's Newton then starts
      // nearer its root).
      at = compliant_tendon_fiber(m, a, L, l_next, at.fiber_velocity_m_s - stiffness * (l_next - l));
      const double g_next = l_next - base - ch * at.fiber_velocity_m_s;
      stiffness = std::max(0.0, ((g_next - g) / (l_next - l) - 1) / ch);
      l = l_next;
      g = g_next;
    }
    lm_prev = lm;
    lm = l;
  }
  return {a, lm, at.force_N};
}

}  // namespace cpgait::muscles
