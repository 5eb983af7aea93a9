#include "cpgait/dynamics/articulated_body.h"

#include <Eigen/Cholesky>

namespace cpgait {

ArticulatedBodyWorkspace::ArticulatedBodyWorkspace(const Model& m)
    : inertia(m.bodies.size()), bias(m.bodies.size()), velocity_product(m.bodies.size()), acceleration(m.bodies.size()),
      U(m.joints.size()), D_inverse(m.joints.size()), u(m.joints.size()) {}

namespace {
// The spatial force cross product v x* f (velocity angular then linear, force moment then force).
Vector6d force_cross(const Vector6d& v, const Vector6d& f) {
  Vector6d r;
  r.head<3>() = v.head<3>().cross(f.head<3>()) + v.tail<3>().cross(f.tail<3>());
  r.tail<3>() = v.head<3>().cross(f.tail<3>());
  return r;
}

// One joint of N coordinates, leaves first: U = I^A S, D^-1, u = tau - S^T p^A, and the subtree's
// articulated inertia and bias passed to the parent (fixed sizes: Eigen unrolls them).
template <int N>
bool resolve_joint(const Joint& j, int k, const double* tau, const DynamicsWorkspace& ws, ArticulatedBodyWorkspace& aw) {
  const int b = j.child_body;
  const Matrix6d& IA = aw.inertia[b];
  const Vector6d& pA = aw.bias[b];
  Eigen::Matrix<double, 6, N> S;
  Eigen::Matrix<double, N, 1> tau_j;
  for (int i = 0; i < N; ++i) {
    S.col(i) = ws.S.columns.col(j.coordinates[i]);
    tau_j[i] = tau[j.coordinates[i]];
  }
  const Eigen::Matrix<double, 6, N> U = IA * S;
  const Eigen::Matrix<double, N, N> D = S.transpose() * U;
  Eigen::Matrix<double, N, N> Dinv;
  if constexpr (N == 1) {
    if (!(D(0, 0) > 0)) return false;
    Dinv(0, 0) = 1.0 / D(0, 0);
  } else {
    const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(D);
    if (llt.info() != Eigen::Success) return false;
    Dinv = llt.solve(Eigen::Matrix<double, N, N>::Identity());
  }
  const Eigen::Matrix<double, N, 1> u = tau_j - S.transpose() * pA;
  aw.U[k].template leftCols<N>() = U;
  aw.D_inverse[k].template topLeftCorner<N, N>() = Dinv;
  aw.u[k].template head<N>() = u;
  if (j.parent_body == 0) return true;
  const Eigen::Matrix<double, 6, N> UD = U * Dinv;
  const Matrix6d Ia = IA - UD * U.transpose();
  aw.inertia[j.parent_body] += Ia;
  aw.bias[j.parent_body] += pA + Ia * aw.velocity_product[b] + UD * u;
  return true;
}

// The same joint, root first: its accelerations given its parent's (a: the parent's plus dS/dt qd).
template <int N>
void joint_accelerations(const Joint& j, int k, const DynamicsWorkspace& ws, ArticulatedBodyWorkspace& aw, Vector6d& a,
                         double* qdd) {
  const auto U = aw.U[k].template leftCols<N>();
  const Eigen::Matrix<double, N, 1> x =
      aw.D_inverse[k].template topLeftCorner<N, N>() * (aw.u[k].template head<N>() - U.transpose() * a);
  for (int i = 0; i < N; ++i) {
    qdd[j.coordinates[i]] = x[i];
    a += ws.S.columns.col(j.coordinates[i]) * x[i];
  }
}

bool resolve_joint_any(const Joint& j, int k, const double* tau, const DynamicsWorkspace& ws, ArticulatedBodyWorkspace& aw) {
  switch (j.coordinates.size()) {
    case 0:
      if (j.parent_body > 0) {
        aw.inertia[j.parent_body] += aw.inertia[j.child_body];
        aw.bias[j.parent_body] += aw.bias[j.child_body] + aw.inertia[j.child_body] * aw.velocity_product[j.child_body];
      }
      return true;
    case 1: return resolve_joint<1>(j, k, tau, ws, aw);
    case 2: return resolve_joint<2>(j, k, tau, ws, aw);
    case 3: return resolve_joint<3>(j, k, tau, ws, aw);
    case 4: return resolve_joint<4>(j, k, tau, ws, aw);
    case 5: return resolve_joint<5>(j, k, tau, ws, aw);
    case 6: return resolve_joint<6>(j, k, tau, ws, aw);
    default: return false;
  }
}

void joint_accelerations_any(const Joint& j, int k, const DynamicsWorkspace& ws, ArticulatedBodyWorkspace& aw, Vector6d& a,
                             double* qdd) {
  switch (j.coordinates.size()) {
    case 1: return joint_accelerations<1>(j, k, ws, aw, a, qdd);
    case 2: return joint_accelerations<2>(j, k, ws, aw, a, qdd);
    case 3: return joint_accelerations<3>(j, k, ws, aw, a, qdd);
    case 4: return joint_accelerations<4>(j, k, ws, aw, a, qdd);
    case 5: return joint_accelerations<5>(j, k, ws, aw, a, qdd);
    case 6: return joint_accelerations<6>(j, k, ws, aw, a, qdd);
    default: return;
  }
}
}  // namespace

bool articulated_body_accelerations(const Model& model, const double* qd, const double* tau,
                                    const std::vector<Vector6d>& external, const DynamicsWorkspace& ws,
                                    ArticulatedBodyWorkspace& aw, double* qdd) {
  const int nj = static_cast<int>(model.joints.size());
  // Each body alone: its inertia, and the force its velocity needs (v x* I v) less what acts on it.
  for (const Joint& j : model.joints) {
    const int b = j.child_body;
    aw.inertia[b] = spatial_inertia_in_ground(model.bodies[b], ws.kinematics.body_in_ground[b]);
    const Vector6d& v = ws.velocity[b];
    aw.bias[b] = force_cross(v, aw.inertia[b] * v);
    if (!external.empty()) aw.bias[b] -= external[b];
    Vector6d c = Vector6d::Zero();
    for (int k : j.coordinates) c += ws.S_rate.col(k) * qd[k];
    aw.velocity_product[b] = c;
  }
  // Leaves first: each joint's subtree, its own coordinates' motion resolved, joins its parent's.
  for (int k = nj - 1; k >= 0; --k)
    if (!resolve_joint_any(model.joints[k], k, tau, ws, aw)) return false;
  // Root first. Gravity enters as the ground accelerating upwards.
  Vector6d a0;
  a0 << Eigen::Vector3d::Zero(), -model.gravity_m_s2;
  for (int k = 0; k < nj; ++k) {
    const Joint& j = model.joints[k];
    Vector6d a = (j.parent_body == 0 ? a0 : aw.acceleration[j.parent_body]) + aw.velocity_product[j.child_body];
    joint_accelerations_any(j, k, ws, aw, a, qdd);
    aw.acceleration[j.child_body] = a;
  }
  return true;
}

}  // namespace cpgait
