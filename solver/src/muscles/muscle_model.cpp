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
  if (m.degroote) return degroote_fregly2016::rigid_tendon_forces(m, a, L, V);
  return m.millard ? millard2012::rigid_tendon_forces(m, a, L, V) : thelen2003::rigid_tendon_forces(m, a, L, V);
}

double rigid_tendon_active_force(const Muscle& m, double a, double L, double V) {
  if (m.rigid_tendon || m.degroote || m.millard) return rigid_tendon_forces(m, a, L, V).active_N;
  return thelen2003::rigid_tendon_active_force(m, a, L, V);
}

double rigid_tendon_fiber_length(const Muscle& m, double L) {
  if (m.rigid_tendon) return rigid_tendon_muscle::fiber_length(m, L);
  if (m.degroote) return degroote_fregly2016::rigid_tendon_fiber_length(m, L);
  return m.millard ? millard2012::rigid_tendon_fiber_length(m, L) : thelen2003::rigid_tendon_fiber(m, L, 0.0).fiber_length_m;
}

CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double a, double L, double lm) {
  if (!m.millard && !m.degroote && !m.rigid_tendon) return thelen2003::compliant_tendon_fiber(m, a, L, lm);  // most muscles
  if (has_rigid_tendon(m)) {  // no fibre state: the force at rest, the fibre held on the path
    const RigidTendonForces f = rigid_tendon_forces(m, a, L, 0.0);
    return {f.active_N + f.passive_N, 0.0, 1.0};
  }
  if (m.degroote) return degroote_fregly2016::compliant_tendon_fiber(m, a, L, lm);
  return m.millard ? millard2012::compliant_tendon_fiber(m, a, L, lm) : thelen2003::compliant_tendon_fiber(m, a, L, lm);
}

double compliant_equilibrium_fiber_length(const Muscle& m, double a, double L, double V) {
  if (has_rigid_tendon(m)) return rigid_tendon_fiber_length(m, L);
  if (m.degroote) return degroote_fregly2016::compliant_equilibrium_fiber_length(m, a, L, V);
  return m.millard ? millard2012::compliant_equilibrium_fiber_length(m, a, L, V)
                   : thelen2003::compliant_equilibrium_fiber_length(m, a, L, V);
}

double isometric_fiber_length(const Muscle& m, double a, double L) {
  return m.schutte ? schutte1993::isometric_fiber_length(m, a, L) : compliant_equilibrium_fiber_length(m, a, L, 0.0);
}

CompliantMuscleState compliant_muscle_after(const Muscle& m, double a, double lm, double L0, double L1, double u, double T) {
  const int n = std::max(1, static_cast<int>(std::ceil(T / 1e-3 - 1e-9)));
  const double h = T / n;
  if (has_rigid_tendon(m)) {
    a = thelen_activation_after(m, a, u, T);
    const RigidTendonForces f = rigid_tendon_forces(m, a, L1, (L1 - L0) / T);
    return {a, rigid_tendon_fiber_length(m, L1), f.active_N + f.passive_N};
  }
  const double lm_min = m.millard ? millard2012::min_fiber_length(m) : thelen2003::min_fiber_length(m);
  for (int i = 1; i <= n; ++i) {
    a = thelen_activation_after(m, a, u, h);
    const double L = L0 + (L1 - L0) * i / n;
    // Backward Euler: g(l) = l - lm - h v(a, L, l) = 0 by Newton with a finite-difference slope;
    // g rises monotonically (v falls as the fibre lengthens), so a safeguarded step always converges.
    double l = lm;
    for (int k = 0; k < 8; ++k) {
      const double v = compliant_tendon_fiber(m, a, L, l).fiber_velocity_m_s;
      const double g = l - lm - h * v;
      const double dl = 1e-7 * m.optimal_fiber_length_m;
      const double dg = 1.0 - h * (compliant_tendon_fiber(m, a, L, l + dl).fiber_velocity_m_s - v) / dl;
      const double step = g / std::max(dg, 1.0);
      l = std::max(l - step, lm_min);
      if (std::abs(step) < 1e-9 * m.optimal_fiber_length_m) break;
    }
    lm = l;
  }
  return {a, lm, compliant_tendon_fiber(m, a, L1, lm).force_N};
}

}  // namespace cpgait::muscles
