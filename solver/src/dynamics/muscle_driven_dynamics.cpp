#include "cpgait/dynamics/muscle_driven_dynamics.h"

#include "cpgait/dynamics/articulated_body.h"
#include "cpgait/dynamics/coordinate_couplers.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/muscle_model.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <limits>

namespace cpgait {

MuscleDrivenWorkspace::MuscleDrivenWorkspace(const MuscleDrivenSystem& sys)
    : fd(*sys.model), articulated(*sys.model), geometry(*sys.model), actuator_columns(sys.num_coordinates(), sys.num_actuators()),
      external(sys.model->bodies.size(), Vector6d::Zero()), tau(sys.num_coordinates()),
      paths(sys.num_muscles()), segments(sys.num_muscles()), muscle_wrench(sys.model->bodies.size(), Vector6d::Zero()),
      muscle_force_N(sys.num_muscles()), fiber_velocity_m_s(Eigen::VectorXd::Zero(sys.num_muscles())),
      active_force_N(Eigen::VectorXd::Zero(sys.num_muscles())),
      actuator_force(sys.num_actuators()) {
  free = free_coordinates(*sys.model);
  for (const auto& mu : sys.model->muscles) rigid_tendon.push_back(muscles::has_rigid_tendon(mu));
  constrained = has_coordinate_constraints(*sys.model);
  if (sys.contacts) {
    for (const auto& s : sys.contacts->spheres) sphere_coordinates.push_back(ancestor_coordinates(*sys.model, s.body));
    contact_force_N.assign(sys.contacts->spheres.size(), Eigen::Vector3d::Zero());
    contact_point_m.assign(sys.contacts->spheres.size(), Eigen::Vector3d::Zero());
  }
}

Eigen::Vector3d point_velocity_in_ground(const MotionSubspace& S, const std::vector<int>& body_coordinates,
                                         const Eigen::Vector3d& p, const double* u) {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  for (int c : body_coordinates) v += point_velocity_column(S, c, p) * u[c];
  return v;
}

void muscle_driven_derivatives(const MuscleDrivenSystem& sys, double t, const Eigen::VectorXd& x,
                               const Eigen::VectorXd& excitation, const Eigen::VectorXd& control,
                               MuscleDrivenWorkspace& ws, Eigen::VectorXd& xdot, MuscleGeometry geometry) {
  const Model& model = *sys.model;
  const bool moment_arms = geometry == MuscleGeometry::kMomentArms;
  const int nq = sys.num_coordinates(), nm = sys.num_muscles(), na = sys.num_actuators();
  const bool coupled = ws.constrained;
  if (coupled) {
    // Locked coordinates held, coupled ones following their independent ones, whatever the state holds.
    ws.x_coupled = x;
    assemble_coordinate_constraints(model, ws.x_coupled.data(), ws.x_coupled.data() + nq);
  }
  const double* q = coupled ? ws.x_coupled.data() : x.data();
  const double* u = q + nq;
  auto& fd = ws.fd;
  rnea_kinematics(model, q, u, fd.dynamics);  // pose, motion subspace and its rate in one pass
  kinematics_values(fd.dynamics, fd.kinematics, fd.S);
  // An integrator's stages on a tree without constraints need the accelerations only: the
  // articulated-body algorithm gives them without M (crba, its factor, the bias and the solve were a
  // fifth of an evaluation on gait2392: callgrind).
  const bool articulated = !moment_arms && !coupled;
  if (!articulated) crba(model, fd.kinematics, fd.S, fd.M, fd.composite);

  ws.time_s = t;
  // External loads: measured, then contact.
  for (auto& e : ws.external) e.setZero();
  if (sys.loads) {
    sys.loads->forces_at(t, fd.kinematics, ws.load_samples);
    for (const auto& f : ws.load_samples) ws.external[f.body] += spatial_force(f.force_N, f.point_m, f.torque_Nm);
  }
  if (sys.contacts) {
    const ContactSet& set = *sys.contacts;
    for (std::size_t i = 0; i < set.spheres.size(); ++i) {
      const ContactSphere& s = set.spheres[i];
      const Eigen::Vector3d centre = sphere_centre_m(fd.kinematics, s);
      // Applied at the contact point below the centre (the sphere's lowest point, not below ground),
      // and slipping at that point's velocity: a rolling foot does not slip. The centre's velocity
      // differs from it by omega x r - on subject01's heel and toe rockers 0.1-0.2 m/s, enough for
      // full friction against a foot the recorded motion rolls without slipping.
      const Eigen::Vector3d point = centre - s.radius_m * Eigen::Vector3d::UnitY();
      const Eigen::Vector3d v = point_velocity_in_ground(fd.S, ws.sphere_coordinates[i], point, u);
      const Eigen::Vector3d f = sphere_contact_force(s, set, centre, v, t);
      ws.contact_force_N[i] = f;
      ws.contact_point_m[i] = point;
      ws.external[s.body] += spatial_force(f, point);
    }
  }
  if (!articulated) rnea_from_kinematics(model, u, fd.zero.data(), ws.external, fd.dynamics, fd.bias.data());  // C + G - J^T f_ext

  // Muscles (rigid tendon) and actuators.
  ws.tau.setZero();
  if (nm > 0) {
    if (moment_arms) {
      muscle_path_geometry(model, q, u, fd.kinematics, fd.S, ws.geometry);
    } else {
      for (int m = 0; m < nm; ++m) {
        current_path(model, model.muscles[m], q, fd.kinematics, ws.paths[m]);
        ws.geometry.length_m[m] = current_path_segments(ws.paths[m], ws.segments[m]);
        // A compliant tendon's force needs the path's length alone (its fibre velocity is a state's rate).
        ws.geometry.lengthening_speed_m_s[m] =
            sys.compliant_tendons && !ws.rigid_tendon[m]
                ? std::numeric_limits<double>::quiet_NaN()
                : current_path_lengthening_speed(ws.paths[m], ws.segments[m], q, u, fd.kinematics, fd.dynamics.velocity);
      }
    }
    for (int m = 0; m < nm; ++m) {
      const Muscle& mu = model.muscles[m];
      const double a = x[sys.activation_index(m)];
      const double l = ws.geometry.length_m[m], v = ws.geometry.lengthening_speed_m_s[m];
      if (sys.compliant_tendons && ws.rigid_tendon[m]) {
        // A muscle whose own tendon is rigid: its fibre state rides along the path.
        const auto f = muscles::rigid_tendon_forces(mu, a, l, v);
        ws.muscle_force_N[m] = f.active_N + f.passive_N;
        const double dl = 1e-7;
        ws.fiber_velocity_m_s[m] = (muscles::rigid_tendon_fiber_length(mu, l + v * dl) - muscles::rigid_tendon_fiber_length(mu, l)) / dl;
        xdot[sys.fiber_length_index(m)] = ws.fiber_velocity_m_s[m];
      } else if (sys.compliant_tendons) {
        // The last evaluation's velocity starts an iterating model's solve (Millard's damped fibre).
        const auto f = muscles::compliant_tendon_fiber(mu, a, l, x[sys.fiber_length_index(m)], ws.fiber_velocity_m_s[m]);
        ws.muscle_force_N[m] = f.force_N;
        ws.fiber_velocity_m_s[m] = f.fiber_velocity_m_s;
        xdot[sys.fiber_length_index(m)] = f.fiber_velocity_m_s;
      } else {
        const auto f = muscles::rigid_tendon_forces(mu, a, l, v);
        ws.active_force_N[m] = f.active_N;
        ws.muscle_force_N[m] = f.active_N + f.passive_N;
      }
      xdot[sys.activation_index(m)] = thelen_activation_rate(mu, excitation[m], a);
    }
    if (moment_arms) {
      ws.tau.noalias() += ws.geometry.moment_arm_m.transpose() * ws.muscle_force_N;
    } else {
      for (auto& w : ws.muscle_wrench) w.setZero();
      for (int m = 0; m < nm; ++m) add_path_tension(ws.paths[m], ws.segments[m], q, fd.kinematics, ws.muscle_force_N[m], ws.muscle_wrench, ws.tau.data());
      add_generalized_forces_of_wrenches(model, fd.S, ws.muscle_wrench, ws.tau.data());
    }
  }
  if (na > 0) {
    sys.actuators->generalized_forces(model, q, fd.kinematics, fd.S, ws.actuator_columns);
    for (int j = 0; j < na; ++j) ws.actuator_force[j] = control[j] * sys.actuators->spec(j).optimal_force;
    ws.tau.noalias() += ws.actuator_columns * control;
  }
  if (sys.generalized_forces) ws.tau += *sys.generalized_forces;
  add_passive_generalized_forces(model, q, u, fd.kinematics, fd.S, ws.tau.data());
  xdot.head(nq) = Eigen::Map<const Eigen::VectorXd>(u, nq);
  if (articulated) {
    if (articulated_body_accelerations(model, u, ws.tau.data(), ws.external, fd.dynamics, ws.articulated, xdot.data() + nq)) return;
    crba(model, fd.kinematics, fd.S, fd.M, fd.composite);  // a joint without motion: M's factor decides
    rnea_from_kinematics(model, u, fd.zero.data(), ws.external, fd.dynamics, fd.bias.data());
  }
  fd.llt.compute(fd.M);  // callers (CMC, the correction controller, the gait) reuse the factor
  if (!coupled) {
    xdot.segment(nq, nq) = fd.llt.solve(ws.tau - fd.bias);
    return;
  }
  // qdd = G qdd_free + c, c the coupled coordinates' scale f'' qd_ind^2; the free accelerations from
  // G^T (M qdd + bias - tau) = 0.
  coupler_velocity_map(model, q, ws.free, ws.G);
  ws.c.setZero(nq);
  for (const auto& cp : model.couplers) ws.c[cp.dependent] = cp.scale * cp.function.second_derivative(q[cp.independent]) * u[cp.independent] * u[cp.independent];
  ws.M_free.noalias() = ws.G.transpose() * fd.M * ws.G;
  const Eigen::VectorXd a_free = ws.M_free.llt().solve(ws.G.transpose() * (ws.tau - fd.bias - fd.M * ws.c));
  xdot.segment(nq, nq) = ws.G * a_free + ws.c;
}

namespace {
// out += scale R^T diag(w) R, over each muscle's crossed coordinates.
void add_moment_arm_product(const MuscleDrivenJacobian& jac, const Eigen::VectorXd& w, double scale, Eigen::MatrixXd& out) {
  for (int m = 0; m < static_cast<int>(jac.crossed.size()); ++m) {
    if (w[m] == 0) continue;
    for (int i : jac.crossed[m])
      for (int j : jac.crossed[m]) out(i, j) += scale * w[m] * jac.moment_arm(m, i) * jac.moment_arm(m, j);
  }
}

// a += R^T diag(w_a) R and b += R^T diag(w_b) R in one pass, each sum as add_moment_arm_product's
// (a zero weight adds zeros to sums that start at +0: the same values).
void add_moment_arm_products(const MuscleDrivenJacobian& jac, const Eigen::VectorXd& w_a, Eigen::MatrixXd& a,
                             const Eigen::VectorXd& w_b, Eigen::MatrixXd& b) {
  for (int m = 0; m < static_cast<int>(jac.crossed.size()); ++m) {
    if (w_a[m] == 0 && w_b[m] == 0) continue;
    for (int i : jac.crossed[m]) {
      const double r_i = jac.moment_arm(m, i), wr_a = w_a[m] * r_i, wr_b = w_b[m] * r_i;
      for (int j : jac.crossed[m]) {
        const double r_j = jac.moment_arm(m, j);
        a(i, j) += wr_a * r_j;
        b(i, j) += wr_b * r_j;
      }
    }
  }
}

// out += scale R^T w and out = R x, over each muscle's crossed coordinates (R is ~1/6 full on gait2392).
void add_moment_arm_transpose_product(const MuscleDrivenJacobian& jac, const Eigen::VectorXd& w, double scale, Eigen::VectorXd& out) {
  for (int m = 0; m < static_cast<int>(jac.crossed.size()); ++m) {
    if (w[m] == 0) continue;
    const double sw = scale * w[m];
    for (int c : jac.crossed[m]) out[c] += sw * jac.moment_arm(m, c);
  }
}
template <typename Vector>
void moment_arm_product(const MuscleDrivenJacobian& jac, const Vector& x, Eigen::VectorXd& out) {
  out.resize(static_cast<Eigen::Index>(jac.crossed.size()));
  for (int m = 0; m < static_cast<int>(jac.crossed.size()); ++m) {
    double sum = 0;
    for (int c : jac.crossed[m]) sum += jac.moment_arm(m, c) * x[c];
    out[m] = sum;
  }
}
}  // namespace

void muscle_driven_prepare(const MuscleDrivenSystem& sys, double t, const Eigen::VectorXd& x,
                           const Eigen::VectorXd& excitation, const Eigen::VectorXd& control, MuscleDrivenWorkspace& ws,
                           MuscleDrivenJacobian& jac, Eigen::VectorXd& xdot) {
  muscle_driven_derivatives(sys, t, x, excitation, control, ws, xdot);
  muscle_driven_jacobian(sys, x, excitation, ws, jac, xdot);
}

void muscle_driven_jacobian(const MuscleDrivenSystem& sys, const Eigen::VectorXd& x, const Eigen::VectorXd& excitation,
                            const MuscleDrivenWorkspace& ws, MuscleDrivenJacobian& jac, const Eigen::VectorXd& xdot) {
  const Model& model = *sys.model;
  const int nm = sys.num_muscles(), nq = sys.num_coordinates();
  jac.M = ws.fd.M;
  if (jac.llt.size() != nq) jac.llt = TreeCholesky(coordinate_parents(model));
  if (jac.whole_w && jac.lu.size() != nq) jac.lu = TreeLU(coordinate_parents(model));
  jac.moment_arm = ws.geometry.moment_arm_m;
  jac.da_da.resize(nm);
  jac.dl_dl.setZero(nm);
  jac.dl_da.setZero(nm);
  jac.dF_dl.setZero(nm);
  jac.dF_da.setZero(nm);
  jac.dF_dV.setZero(nm);
  jac.dF_dL.setZero(nm);
  jac.dl_dL.setZero(nm);
  for (int m = 0; m < nm; ++m) {
    const Muscle& mu = model.muscles[m];
    const double a = x[sys.activation_index(m)];
    const double L = ws.geometry.length_m[m], V = ws.geometry.lengthening_speed_m_s[m];
    const double da = 1e-6;
    jac.da_da[m] = (thelen_activation_rate(mu, excitation[m], a + da) - xdot[sys.activation_index(m)]) / da;
    if (sys.compliant_tendons && muscles::has_rigid_tendon(mu)) {
      continue;  // no stiff fibre state; its force-velocity damping is left explicit
    } else if (sys.compliant_tendons) {
      const double lm = x[sys.fiber_length_index(m)], dl = 1e-7 * mu.optimal_fiber_length_m;
      const double v = ws.fiber_velocity_m_s[m];  // the evaluation at x: a start that needs no step
      const auto f0 = muscles::compliant_tendon_fiber(mu, a, L, lm, v);
      const auto fl = muscles::compliant_tendon_fiber(mu, a, L, lm + dl, v);
      const auto fa = muscles::compliant_tendon_fiber(mu, a + da, L, lm, v);
      const auto fL = muscles::compliant_tendon_fiber(mu, a, L + dl, lm, v);
      jac.dl_dl[m] = (fl.fiber_velocity_m_s - f0.fiber_velocity_m_s) / dl;
      jac.dl_da[m] = (fa.fiber_velocity_m_s - f0.fiber_velocity_m_s) / da;
      jac.dF_dl[m] = (fl.force_N - f0.force_N) / dl;
      jac.dF_dL[m] = (fL.force_N - f0.force_N) / dl;
      jac.dl_dL[m] = (fL.fiber_velocity_m_s - f0.fiber_velocity_m_s) / dl;
    } else {
      const double F = ws.active_force_N[m];
      const double dV = 1e-6 * mu.optimal_fiber_length_m * mu.max_contraction_velocity;
      jac.dF_da[m] = (muscles::rigid_tendon_active_force(mu, a + da, L, V) - F) / da;
      jac.dF_dV[m] = std::max(0.0, (muscles::rigid_tendon_active_force(mu, a, L, V + dV) - F) / dV);
      if (jac.whole_w) {
        const double dL = 1e-7 * mu.optimal_fiber_length_m;
        const auto fL = muscles::rigid_tendon_forces(mu, a, L + dL, V);
        jac.dF_dL[m] = std::max(0.0, (fL.active_N + fL.passive_N - ws.muscle_force_N[m]) / dL);
      }
    }
  }
  jac.factored_gamma_h = -1;
  // R^T diag(.) R products go muscle by muscle over the few coordinates each one crosses (a dense
  // product was 6 % of a reproduced gait's time).
  if (static_cast<int>(jac.spanned.size()) != nm) {
    jac.spanned.clear();
    for (const Muscle& mu : model.muscles) jac.spanned.push_back(spanned_coordinates(model, mu));
  }
  jac.crossed.resize(nm);
  for (int m = 0; m < nm; ++m) {
    jac.crossed[m].clear();
    for (int c : jac.spanned[m])
      if (jac.moment_arm(m, c) != 0) jac.crossed[m].push_back(c);
  }
  jac.damping.setZero(nq, nq);
  jac.stiffness.setZero(nq, nq);
  if (!sys.compliant_tendons && nm > 0) {
    jac.muscle_damping.setZero(nq, nq);
    if (jac.whole_w) add_moment_arm_products(jac, jac.dF_dV, jac.muscle_damping, jac.dF_dL, jac.stiffness);
    else add_moment_arm_product(jac, jac.dF_dV, 1.0, jac.muscle_damping);
  }
  // Contact: each sphere's force (as the evaluation above found it) against its contact point's
  // velocity and its height, by differences, mapped through the contact point's velocity Jacobian.
  if (sys.contacts && !sys.contacts->spheres.empty()) {
    const ContactSet& set = *sys.contacts;
    const double* u = x.data() + nq;
    Eigen::Matrix<double, 3, Eigen::Dynamic> J(3, nq);
    for (std::size_t i = 0; i < set.spheres.size(); ++i) {
      const ContactSphere& s = set.spheres[i];
      const Eigen::Vector3d& f0 = ws.contact_force_N[i];
      if (f0.y() < 1e-6) continue;  // not touching: nothing stiff
      const Eigen::Vector3d& p = ws.contact_point_m[i];
      const Eigen::Vector3d c = p + s.radius_m * Eigen::Vector3d::UnitY();
      const Eigen::Vector3d v = point_velocity_in_ground(ws.fd.S, ws.sphere_coordinates[i], p, u);
      Eigen::Matrix3d C;
      const double dv = 1e-6;
      for (int j = 0; j < 3; ++j) C.col(j) = -(sphere_contact_force(s, set, c, v + dv * Eigen::Vector3d::Unit(j), ws.time_s) - f0) / dv;
      Eigen::Matrix3d C_w = C;
      if (!jac.whole_w) {
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (C + C.transpose()));
        const Eigen::Matrix3d C_psd = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
        C_w = C_psd;
      }
      const double dp = 1e-7;
      const double k_yy = std::max(0.0, -(sphere_contact_force(s, set, c + dp * Eigen::Vector3d::UnitY(), v, ws.time_s).y() - f0.y()) / dp);
      // Over the sphere's ancestor coordinates only (its Jacobian's nonzero columns): a dense
      // J^T C J was 3 % of a reproduced gait's time.
      const std::vector<int>& cs = ws.sphere_coordinates[i];
      const int nc = static_cast<int>(cs.size());
      for (int a = 0; a < nc; ++a) J.col(a) = point_velocity_column(ws.fd.S, cs[a], p);
      const auto Jc = J.leftCols(nc);
      const Eigen::Matrix<double, Eigen::Dynamic, 3> JtC = Jc.transpose() * C_w;
      for (int b = 0; b < nc; ++b)
        for (int a = 0; a < nc; ++a) {
          jac.damping(cs[a], cs[b]) += JtC.row(a).dot(Jc.col(b));
          jac.stiffness(cs[a], cs[b]) += k_yy * Jc(1, a) * Jc(1, b);
        }
    }
  }
}

void muscle_driven_w_solve(const MuscleDrivenSystem& sys, MuscleDrivenJacobian& jac, double gh, const Eigen::VectorXd& rhs,
                           Eigen::VectorXd& k) {
  const int nq = sys.num_coordinates(), nm = sys.num_muscles();
  k.resize(rhs.size());
  jac.g.setZero(nm);
  // Compliant tendons: a joint motion dq stretches each path by dL = -R dq, which moves the tendon's
  // force directly and through the fibre's response within the step. Eliminating the fibre gives the
  // effective stiffness e = dF/dL + dF/dl gh (dl'/dL) / (1 - gh dl'/dl): with it in W the stiff
  // tendons on light segments (toes, ankles) no longer limit the step. Where e < 0 the coupling is
  // left out (W stays positive definite; a W-method keeps its order with any approximation).
  const bool tendon_stiffness = sys.compliant_tendons && nm > 0;
  if (tendon_stiffness && gh != jac.factored_gamma_h) {
    jac.tendon_stiffness.resize(nm);
    for (int m = 0; m < nm; ++m) {
      const double e = jac.dF_dL[m] + jac.dF_dl[m] * gh * jac.dl_dL[m] / (1.0 - gh * jac.dl_dl[m]);
      jac.tendon_stiffness[m] = e > 0 ? e : 0.0;
    }
  }
  for (int m = 0; m < nm; ++m) {
    const int ia = sys.activation_index(m);
    k[ia] = rhs[ia] / (1.0 - gh * jac.da_da[m]);
    if (sys.compliant_tendons) {
      const int il = sys.fiber_length_index(m);
      k[il] = (rhs[il] + gh * jac.dl_da[m] * k[ia]) / (1.0 - gh * jac.dl_dl[m]);  // the part without dL
      jac.g[m] = jac.dF_dl[m] * k[il];
    } else {
      jac.g[m] = jac.dF_da[m] * k[ia];
    }
  }
  // (M + gh (R^T diag(dF/dV) R + D) + gh^2 (K + R^T diag(e) R)) k_u
  //   = M rhs_u + gh R^T g - gh (K + R^T diag(e) R) rhs_q,  with k_q = rhs_q + gh k_u
  if (gh != jac.factored_gamma_h) {
    jac.W = jac.M;
    if (!sys.compliant_tendons && nm > 0) jac.W += gh * jac.muscle_damping;
    jac.W += gh * jac.damping + gh * gh * jac.stiffness;
    if (tendon_stiffness) add_moment_arm_product(jac, jac.tendon_stiffness, gh * gh, jac.W);
    if (jac.whole_w) jac.lu.compute(jac.W);
    else jac.llt.compute(jac.W);
    jac.factored_gamma_h = gh;
  }
  Eigen::VectorXd& b = jac.b;
  b.noalias() = jac.M * rhs.segment(nq, nq);
  if (nm > 0) add_moment_arm_transpose_product(jac, jac.g, gh, b);
  b.noalias() -= gh * jac.stiffness * rhs.head(nq);
  Eigen::VectorXd& stretch = jac.stretch;  // R dq = -dL per muscle
  if (tendon_stiffness) {
    moment_arm_product(jac, rhs.head(nq), stretch);  // the stretch the position part alone makes
    stretch.array() *= jac.tendon_stiffness.array();
    add_moment_arm_transpose_product(jac, stretch, -gh, b);
  }
  k.segment(nq, nq) = jac.whole_w ? jac.lu.solve(b) : jac.llt.solve(b);
  k.head(nq) = rhs.head(nq) + gh * k.segment(nq, nq);
  if (tendon_stiffness) {
    // The fibres' response to the joints' motion over the step, where the coupling was kept.
    moment_arm_product(jac, k.head(nq), stretch);
    for (int m = 0; m < nm; ++m)
      if (jac.tendon_stiffness[m] > 0)
        k[sys.fiber_length_index(m)] -= gh * jac.dl_dL[m] * stretch[m] / (1.0 - gh * jac.dl_dl[m]);
  }
}

}  // namespace cpgait
