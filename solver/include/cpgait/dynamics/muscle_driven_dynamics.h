#pragma once
// The muscle-driven model's state derivative: skeleton (CRBA + RNEA bias), each muscle by its own
// model (muscles/muscle_model.h: Millard2012EquilibriumMuscle or Thelen 2003) with Thelen's
// first-order activation dynamics, ideal actuators (residuals, reserves), the model's passive
// generalized forces, and either measured external loads (GRF) or foot-ground contact spheres.
//
// State x = [q (nq), u = dq/dt (nq), activation (muscles), fibre length (muscles, compliant tendons
// only)]. Inputs per evaluation: muscle excitations and actuator controls at that time (the caller
// decides how they vary in time).
//
// Compliant tendons (as OpenSim's muscles integrate them): the fibre length is a state and the force
// is the tendon's (muscles::compliant_tendon_fiber). Rigid tendons: the fibre follows the path
// (constant-thickness pennation), the force is a * F_active(l, v) + F_passive(l) and the only muscle
// state is activation; what static optimization assumes. Rigid tendons overestimate passive forces
// when a muscle is stretched (late swing's hamstrings by ~5x on gait2392), because the tendon does
// not take up any of the stretch.
#include <Eigen/Core>
#include <vector>

#include "cpgait/activation/actuators.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/dynamics/articulated_body.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/dynamics/forward_dynamics.h"
#include "cpgait/dynamics/tree_cholesky.h"
#include "cpgait/dynamics/tree_lu.h"
#include "cpgait/muscles/muscle_path.h"

namespace cpgait {

struct MuscleDrivenSystem {
  const Model* model = nullptr;
  const ResolvedActuators* actuators = nullptr;  // nullptr: none
  const AppliedLoads* loads = nullptr;           // measured loads at time t; nullptr: none
  const ContactSet* contacts = nullptr;          // contact spheres; nullptr: none
  bool compliant_tendons = true;
  // Further generalized forces (N m or N per coordinate) added in every evaluation, e.g. residuals or
  // passive joints the caller updates before each call; nullptr: none.
  const Eigen::VectorXd* generalized_forces = nullptr;
  int num_coordinates() const { return model->num_coordinates(); }
  int num_muscles() const { return static_cast<int>(model->muscles.size()); }
  int num_actuators() const { return actuators ? actuators->size() : 0; }
  int state_size() const { return 2 * num_coordinates() + (compliant_tendons ? 2 : 1) * num_muscles(); }
  int activation_index(int muscle) const { return 2 * num_coordinates() + muscle; }
  int fiber_length_index(int muscle) const { return 2 * num_coordinates() + num_muscles() + muscle; }
};

// Per-thread scratch space; after each evaluation it also holds that evaluation's forces.
struct MuscleDrivenWorkspace {
  ForwardDynamicsWorkspace fd;
  ArticulatedBodyWorkspace articulated;
  MusclePathGeometry geometry;
  Eigen::MatrixXd actuator_columns;  // nq x actuators: generalized force per unit control
  std::vector<Vector6d> external;
  std::vector<AppliedLoads::Sample> load_samples;
  std::vector<std::vector<int>> sphere_coordinates;  // coordinates moving each sphere's body
  Eigen::VectorXd tau;
  // Coupler constraints and locked coordinates: the state assembled on them, and the projection's parts.
  bool constrained = false;
  Eigen::VectorXd x_coupled, c;
  std::vector<int> free;
  Eigen::MatrixXd G, M_free;
  std::vector<char> rigid_tendon;  // per muscle: its own model's tendon is inextensible
  std::vector<std::vector<PathVertex<double>>> paths;  // per muscle (MuscleGeometry::kLengthsAndSpeeds)
  std::vector<std::vector<StretchingSegment>> segments;  // per muscle: its path's stretching segments
  std::vector<Vector6d> muscle_wrench;                  // per body: the muscles' tensions
  // Outputs of the last evaluation.
  double time_s = 0;
  Eigen::VectorXd muscle_force_N;      // along the tendon
  Eigen::VectorXd fiber_velocity_m_s;  // compliant tendons: d(fibre length)/dt
  Eigen::VectorXd active_force_N;      // rigid tendons: the active part of muscle_force_N
  Eigen::VectorXd actuator_force;      // N or N m
  std::vector<Eigen::Vector3d> contact_force_N, contact_point_m;  // per sphere, ground frame
  explicit MuscleDrivenWorkspace(const MuscleDrivenSystem& sys);
};

// What an evaluation leaves in ws.geometry. kLengthsAndSpeeds: no moment-arm matrix (moment_arm_m
// stays as it was), and no lengthening speed (NaN) for a muscle whose compliant tendon does not use it; the muscles' tensions reach the joints as their paths' body forces
// (muscle_path.h: the same generalized forces to rounding), for an integrator's stages that nobody
// reads the moment arms of. The Jacobian needs them: muscle_driven_prepare forms them. On a model
// without coupler constraints or locked coordinates kLengthsAndSpeeds also leaves ws.fd's M, factor
// and bias as the last kMomentArms evaluation left them (the accelerations come from the
// articulated-body algorithm).
enum class MuscleGeometry { kMomentArms, kLengthsAndSpeeds };

// xdot = f(t, x); excitation per muscle (clamped to its control range), control per actuator.
void muscle_driven_derivatives(const MuscleDrivenSystem& sys, double t_s, const Eigen::VectorXd& x,
                               const Eigen::VectorXd& excitation, const Eigen::VectorXd& control,
                               MuscleDrivenWorkspace& ws, Eigen::VectorXd& xdot,
                               MuscleGeometry geometry = MuscleGeometry::kMomentArms);

// The Jacobian approximation integrate_ros2 uses: the stiff parts only. Per muscle, the activation
// and fibre-length rates against their own states (diagonal), the muscle force against fibre length
// and path length (compliant: the tendon's stiffness couples the joints, R^T diag(e) R) or against
// activation and path speed (rigid: the force-velocity curve damps the joints, -R^T diag(dF/dV) R),
// dq/dt = u, and the damping and stiffness below (contact, and what a caller adds). Measured GRF
// moving with the body is left explicit: the W-method stays second order with any such
// approximation.
struct MuscleDrivenJacobian {
  Eigen::MatrixXd M, moment_arm;  // at the step's start
  Eigen::VectorXd da_da, dl_dl, dl_da, dF_dl, dF_da, dF_dV;
  Eigen::VectorXd dF_dL, dl_dL;     // compliant tendons: force and fibre velocity against path length
  Eigen::VectorXd tendon_stiffness;  // compliant: effective dF/dL over a step of factored_gamma_h (>= 0)
  std::vector<std::vector<int>> crossed;  // per muscle: the coordinates with a nonzero moment arm
  std::vector<std::vector<int>> spanned;  // per muscle: spanned_coordinates, where crossed is looked for
  // Generalized damping and stiffness (nq x nq, symmetric, >= 0) of the forces outside the muscles.
  // Contact spheres give sum J^T C J (C: -dF/dv, symmetric part, negative eigenvalues dropped) and
  // sum k J_y^T J_y, the stiff terms of foot-ground contact (friction's slope near zero slip and the
  // Hunt-Crossley normal force); a caller adds its own generalized forces' (passive joints).
  Eigen::MatrixXd damping, stiffness;
  Eigen::MatrixXd muscle_damping;  // rigid tendons: R^T diag(dF/dV) R, formed once per prepare
  // The W a one-stage method without error control needs (default false: the symmetric W above,
  // factored by Cholesky). True: the contact's damping as it is, -dF/dv unsymmetrized (friction
  // follows the normal force, which follows the normal speed; the symmetric part halved that
  // coupling and the linearly implicit Euler diverged on subject01 at 2 ms), the rigid tendons'
  // R^T diag(dF/dL) R in the stiffness, and W factored by TreeLU (elimination on the tree's pattern
  // without pivoting; partial pivoting where a pivot is not positive).
  bool whole_w = false;
  Eigen::MatrixXd W;  // M + gamma h (R^T diag(dF/dV) R + D) + (gamma h)^2 (K + R^T diag(e) R), factored in llt (lu: whole_w)
  TreeCholesky llt;
  TreeLU lu;  // whole_w's factor
  double factored_gamma_h = -1;   // the gamma h that llt holds (a step's stages share it); < 0: none
  Eigen::VectorXd g, b, stretch;  // w_solve's scratch
};

// xdot at (t, x) and the Jacobian approximation there.
void muscle_driven_prepare(const MuscleDrivenSystem& sys, double t_s, const Eigen::VectorXd& x,
                           const Eigen::VectorXd& excitation, const Eigen::VectorXd& control, MuscleDrivenWorkspace& ws,
                           MuscleDrivenJacobian& jac, Eigen::VectorXd& xdot);
// The Jacobian part alone, for a caller whose ws and xdot already hold the evaluation at x (with
// these excitations' activation rates): muscle forces, geometry and contact do not depend on the
// excitations, so an evaluation made before they changed serves once the rates are redone.
void muscle_driven_jacobian(const MuscleDrivenSystem& sys, const Eigen::VectorXd& x, const Eigen::VectorXd& excitation,
                            const MuscleDrivenWorkspace& ws, MuscleDrivenJacobian& jac, const Eigen::VectorXd& xdot);
// k = (I - gamma_h J)^-1 rhs with the prepared J (block triangular: activation, fibre, then speed and
// position together through the contact terms and the tendons, then the fibres' share of the joints'
// motion).
void muscle_driven_w_solve(const MuscleDrivenSystem& sys, MuscleDrivenJacobian& jac, double gamma_h,
                           const Eigen::VectorXd& rhs, Eigen::VectorXd& k);

// Velocity (ground frame) of a point fixed on `body`, given the kinematics and motion subspace at q.
Eigen::Vector3d point_velocity_in_ground(const MotionSubspace& S, const std::vector<int>& body_coordinates,
                                         const Eigen::Vector3d& point_G_m, const double* u);

}  // namespace cpgait
